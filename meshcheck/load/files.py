"""One file -> cleaned mesh arrays, in this process or in the run's worker processes.

``read_files`` reads every file of a run. Files are read here one after another, or, when the
reading they hold pays for starting workers and shipping the arrays back (``parallel_pays``),
mesh files (``WORKER_EXTENSIONS``) are read in the executor's local processes while STEP and 3MF
files are read here. Either way the outcome is the one a serial read gives, bit for bit:

- a worker returns plain arrays (``FileRead``), and the meshes are built from them here, the
  same way a serial read builds them;
- the run's ``Budget`` is kept here in file order: a worker reads each file against an empty
  budget and records every budget check it made, which is replayed here against the real one
  (a check that passes here passed there: the budget only grows);
- the warnings a worker's reading raised are raised again here, in file order, interleaved
  with the budget checks as they happened;
- the first file in argument order that cannot be read is the error raised, whatever order the
  workers finish in; a file whose worker died is read again here.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import trimesh

from .. import units as units_
from ..errors import InputError, MeshcheckError, MeshcheckWarning
from ..geometry import topology
from ..mesh import as_mesh, clean_arrays, warn
from .formats import STEP_EXTENSIONS, SUPPORTED_EXTENSIONS, URDF_EXTENSIONS
from .gltf import read_gltf
from .limits import MAX_TEXT_LINE, Budget, Limits, read_file
from .robot import Robot
from .scene import STL_HEADER, STL_RECORD, read_scene, stores_float32
from .threemf import read_3mf

if TYPE_CHECKING:
    from ..cache import TessellationCache
    from .step import StepSolids

#: Read in worker processes when reading in parallel. STEP stays here (its tessellation cache
#: is written by this process only, and its exact solids stay here), and so does 3MF (its
#: reader sizes its stream by what the run's budget has left, which only this process knows).
WORKER_EXTENSIONS = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")

#: Estimated seconds of worker time per byte of a file: reading, cleaning, closedness, shells.
#: Binary formats (STL as CAD writes it, binary PLY, GLB) are fast to parse; text is ~10x slower.
#: bench/load_parallel.py: ~23 kB binary STL files 0.18 ms each (8e-9 s/B); ~13 kB OBJ files
#: 1.0 ms each (7.5e-8 s/B). An ASCII STL is counted as binary: the estimate errs on serial.
SECONDS_PER_BYTE = {
    ".stl": 8e-9, ".ply": 8e-9, ".glb": 8e-9, ".obj": 75e-9, ".off": 75e-9, ".gltf": 75e-9,
}  # fmt: skip
#: Seconds per file that reading in a worker adds here: the arrays' trip back, checks replayed.
SECONDS_PER_FILE = 1e-4
#: Seconds a pool of fresh workers costs before it reads anything (their imports, in parallel).
START_SECONDS = 0.6
#: Files per task sent to a worker: enough to amortise a message, few enough to balance.
FILES_PER_TASK = 64


@dataclass(frozen=True)
class StepOptions:
    """How STEP files are tessellated (``load.step``)."""

    deflection: float | None
    units: str | None
    motion: object = None  # motion.Motion: the pose and package paths of URDF files
    #: (path, unit) of the files whose unit the user gave (``--units FILE=UNIT``), sorted
    given_units: tuple[tuple[str, str], ...] = ()

    def for_file(self, path: str) -> tuple[float | None, str | None, str | None]:
        """(deflection, its unit, the unit the user gave ``path``) as ``read_step`` takes
        them (``deflection``, ``deflection_unit``, ``unit``)."""
        unit = (self.units or units_.DEFAULT_UNIT) if self.deflection is not None else None
        return self.deflection, unit, dict(self.given_units).get(path)


@dataclass(frozen=True)
class FileRead:
    """One file read and cleaned, as plain arrays (what a worker process sends back).

    Attributes
    ----------
    items : list of (str, int, (4, 4) float64)
        (node, index into ``geometries``, placement in the file's unit), sorted by node.
    geometries : list of ((n, 3) float64, (m, 3) int64, bool)
        Each distinct cleaned mesh once: vertices, faces, and whether it is closed.
    declared : str or None
        The unit the file declares.
    deflection : float
        How far its triangles may lie from the true surface, in that unit (0 for mesh files):
        the largest of ``deflections``.
    deflections : tuple of float
        Each geometry's own deflection (a STEP product whose faces were meshed again may hold
        more than the others); empty when every geometry holds ``deflection``.
    sources : tuple of str
        Each geometry's ``Body.source_digest`` (a STEP product's B-rep); empty for other files.
    is_float32 : bool
        Whether the reader got the coordinates through float32 (``Body.is_float32``).
    robot : robot.Robot or None
        The robot a URDF describes (its items are the robot's collision elements); None for
        other files.
    solids : step.StepSolids or None
        A STEP file's exact solids (``Body.brep``), read in this process only; None otherwise.
    elements : dict of str -> tuple of body.PartElement
        The collision elements of each URDF link made of several (``Body.elements``), by node.
    """

    items: list[tuple[str, int, np.ndarray]]
    geometries: list[tuple[np.ndarray, np.ndarray, bool]]
    declared: str | None
    deflection: float
    is_float32: bool = True
    robot: Robot | None = None
    solids: StepSolids | None = None
    elements: dict = dataclasses.field(default_factory=dict)
    deflections: tuple[float, ...] = ()
    sources: tuple[str, ...] = ()

    def deflection_of(self, geometry: int) -> float:
        """The deflection geometry ``geometry`` holds, in the file's unit."""
        return self.deflections[geometry] if self.deflections else self.deflection

    def source_of(self, geometry: int) -> str:
        """Geometry ``geometry``'s ``Body.source_digest`` (empty: none)."""
        return self.sources[geometry] if self.sources else ""

    @property
    def triangles(self) -> int:
        """Triangles of every placed item."""
        return sum(len(self.geometries[g][1]) for _, g, _ in self.items)

    def meshes(self) -> list[trimesh.Trimesh]:
        """A mesh for each geometry (its instances share it)."""
        return [as_mesh(v, f, closed=closed) for v, f, closed in self.geometries]


def is_multi(path: str, items: Sequence) -> bool:
    """Whether a file's parts are named ``PATH#NODE`` (several parts, or any STEP solid)."""
    ext = os.path.splitext(path)[1].lower()
    return len(items) > 1 or ext in STEP_EXTENSIONS or ext in URDF_EXTENSIONS


def read(
    path: str,
    budget: Budget,
    step: StepOptions,
    cache: TessellationCache | None = None,
    executor=None,
) -> FileRead:
    """Read and clean one file, checked against and counted in ``budget``.

    Parameters
    ----------
    path : str
    budget : Budget
        The run's budget; the file's triangles and parts are taken from it.
    step : StepOptions
    cache : cache.TessellationCache, optional
        The run's STEP tessellations.
    executor : execute.Executor, optional
        The run's executor, for a STEP file's products (``step.read_step``).

    Raises
    ------
    InputError
        The file cannot be checked (see ``meshcheck.load``).
    """
    out = _read(path, budget, step, cache, executor)
    budget.take(path, out.triangles, len(out.items))
    return out


def _read(
    path: str,
    budget: Budget,
    step: StepOptions,
    cache: TessellationCache | None = None,
    executor=None,
) -> FileRead:
    """``read`` without taking from the budget (its checks still run)."""
    if not os.path.exists(path):
        raise InputError(path, "no such file or directory")
    if os.path.isdir(path):
        raise InputError(path, "is a directory")
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise InputError(
            path,
            f"unsupported file type {ext or '(no extension)'}; "
            f"supported: {', '.join(SUPPORTED_EXTENSIONS)}",
        )
    data = read_file(
        path,
        budget.limits,
        check=_stl_head_check(path, budget) if ext == ".stl" else None,
        max_line=MAX_TEXT_LINE if ext in (".obj", ".off") else None,
    )
    declared, deflection, robot, solids = None, 0.0, None, None
    # Which coordinates went through float32, per reader: glTF (POSITION accessors are float32),
    # binary STL and float PLY; 3MF, text meshes and STEP (OpenCASCADE's mesher, double
    # placements, a float64 tessellation cache) are double.
    is_float32 = ext in (".glb", ".gltf") or stores_float32(ext, data)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # refused below with the real reason
        # A reader takes (path, bytes, budget) and returns (node, mesh, placement) items and the
        # unit the file declares (None: undeclared). A STEP reader plugs in here the same way.
        if ext in STEP_EXTENSIONS:
            items, declared, deflection, solids = _read_step(
                path, data, step, budget, cache, executor
            )
        elif ext in URDF_EXTENSIONS:
            from .urdf import read_urdf

            (robot, items), declared = read_urdf(path, data, budget, step.motion), "m"
        elif ext == ".3mf":
            items, declared = read_3mf(path, data, budget)
        elif ext in (".glb", ".gltf"):
            items, declared = read_gltf(path, data, ext, budget), "m"
        else:
            items = read_scene(path, data, ext, budget)
    del data

    multi = is_multi(path, items)
    index: dict[int, int] = {}  # id(geometry) -> its index: cleaned once, shared by instances
    geometries: list[tuple[np.ndarray, np.ndarray, bool]] = []
    deflections: list[float] = []
    sources: list[str] = []
    out = []
    for node, geom, transform in sorted(items, key=lambda item: item[0]):
        name = f"{path}#{node}" if multi else path
        if id(geom) not in index:
            v, f = clean_arrays(
                geom.vertices,
                geom.faces,
                name,
                max_coordinate=budget.limits.max_coordinate,
                shells=_shells(geom) if ext in STEP_EXTENSIONS else None,
            )
            closed = topology.is_closed(f)
            index[id(geom)] = len(geometries)
            geometries.append((v, f, closed))
            metadata = getattr(geom, "metadata", {})
            deflections.append(float(metadata.get("deflection", deflection)))
            sources.append(str(metadata.get("brep", "")))
        g = index[id(geom)]
        if not geometries[g][2]:
            warn(name, "mesh is not closed (not watertight); its findings rest on surfaces only")
        out.append((node, g, np.asarray(transform, dtype=np.float64)))
    return FileRead(
        out,
        geometries,
        declared,
        float(deflection),
        is_float32=is_float32,
        robot=robot,
        solids=solids,
        elements={node: geom.elements for node, geom, _ in items if hasattr(geom, "elements")},
        deflections=tuple(deflections) if ext in STEP_EXTENSIONS else (),
        sources=tuple(sources) if ext in STEP_EXTENSIONS else (),
    )


def _shells(mesh) -> np.ndarray:
    """(n,) int64: the connected shell of each vertex of a mesh welded as read (a STEP part's
    solids, each welded on its own: vertices where two solids meet stay apart)."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    face_label, _ = topology.shell_labels(faces, len(mesh.vertices))
    labels = np.full(len(mesh.vertices), -1, dtype=np.int64)
    labels[faces] = np.asarray(face_label, dtype=np.int64)[:, None]
    return labels


def _stl_head_check(path: str, budget: Budget):
    """A check of a binary STL's declared triangles against the budget, before it is read."""

    def check(head: bytes, size: int) -> None:
        if len(head) >= STL_HEADER:
            count = int.from_bytes(head[80:84], "little")
            if size == STL_HEADER + STL_RECORD * count:
                budget.check_triangles(path, count)

    return check


def _read_step(
    path: str,
    data: bytes,
    options: StepOptions,
    budget: Budget,
    cache: TessellationCache | None,
    executor=None,
):
    """(items, declared unit, deflection in that unit, exact solids) of a STEP file."""
    from .step import read_step

    deflection, deflection_unit, unit = options.for_file(path)
    try:
        assembly = read_step(
            path,
            data=data,
            deflection=deflection,
            deflection_unit=deflection_unit,
            unit=unit,
            cache=cache,
            max_triangles=budget.limits.max_triangles - budget.triangles,
            executor=executor,
        )
    except ValueError as exc:
        raise InputError(path, str(exc)) from None
    return list(assembly.items), assembly.unit, float(assembly.deflection), assembly.solids


# --------------------------------------------------------------------------------------------
# Many files, here or in worker processes


def read_files(
    paths: Sequence[str],
    budget: Budget,
    step: StepOptions,
    *,
    cache: TessellationCache | None = None,
    executor=None,
    progress: Callable[[int, int], None] | None = None,
    parallel: bool | None = None,
) -> list[FileRead]:
    """``read`` of every file, in order; in ``executor``'s processes when it pays.

    Parameters
    ----------
    paths : sequence of str
        Files, in argument order.
    budget, step, cache
        As for ``read``.
    executor : execute.Executor, optional
        The run's executor. Files of ``WORKER_EXTENSIONS`` are read in its processes when it has
        local ones (``jobs > 1``; not a Dask cluster: loading stays on the client) and
        ``parallel`` says so.
    progress : callable, optional
        Called as ``progress(done, total)`` as files are read.
    parallel : bool, optional
        True: read in the executor's processes whenever it has local ones; False: never;
        None (default): when ``parallel_pays``.

    Raises
    ------
    InputError
        The first file in ``paths`` that cannot be checked, as a serial read raises it.
    """
    total = len(paths)
    in_workers = [
        k for k, p in enumerate(paths) if os.path.splitext(p)[1].lower() in WORKER_EXTENSIONS
    ]
    local = executor is not None and not executor.is_distributed and executor.jobs > 1
    steps = [k for k, p in enumerate(paths) if os.path.splitext(p)[1].lower() in STEP_EXTENSIONS]

    def read_here(k: int) -> FileRead:
        if local and len(steps) > 1 and k == steps[1]:
            # The first STEP file was read ahead in a worker (``load.step.ahead``); the others
            # are read in the pool now, the first of them reached.
            _read_steps_in_pool([paths[j] for j in steps[1:]], budget, step, cache, executor)
        return read(paths[k], budget, step, cache, executor)

    if parallel is None and local:
        parallel = parallel_pays([paths[k] for k in in_workers], executor.jobs)
    if not (local and parallel and in_workers):
        out = []
        for k in range(total):
            out.append(read_here(k))
            if progress is not None:
                progress(k + 1, total)
        return out

    from ..execute import Task

    per_task = max(1, min(FILES_PER_TASK, len(in_workers) // (4 * executor.jobs)))
    chunks = [in_workers[a : a + per_task] for a in range(0, len(in_workers), per_task)]
    tasks = [
        Task(
            ([paths[k] for k in chunk], budget.limits, step),
            size=_size(paths[k] for k in chunk),
        )
        for chunk in chunks
    ]

    def report(done_tasks: int) -> None:  # files read by the workers, roughly
        if progress is not None:
            progress(min(done_tasks * per_task, len(in_workers)), total)

    results = executor.map("meshcheck.load.files:read_task", tasks, progress=report)
    outcome: dict[int, tuple] = {}
    for chunk, result in zip(chunks, results, strict=True):
        for k, one in zip(chunk, result or (), strict=False):
            outcome[k] = one  # a chunk stops at its first failing file; a lost one gives None

    out = []
    done = len(in_workers)
    for k, path in enumerate(paths):
        if k in outcome:
            out.append(_replay(path, budget, outcome[k]))
        else:  # a main-process format, or its worker died: read it here
            out.append(read_here(k))
            done = min(done + 1, total)
            if progress is not None:
                progress(done, total)
    return out


def _read_steps_in_pool(
    paths: list[str], budget: Budget, step: StepOptions, cache, executor
) -> None:
    """Have ``executor``'s pool read the STEP files ``paths`` (``step.ahead.read_in_pool``),
    with the options ``_read_step`` gives ``read_step``; ``read_step`` then takes what it read
    (the same products), or reads a file here when it did not."""
    from .step import ahead
    from .step.tessellate import MAX_STEP_TRIANGLES

    options = [step.for_file(path) for path in paths]
    most = min(budget.limits.max_triangles, MAX_STEP_TRIANGLES)  # a file's triangles at most
    ahead.read_in_pool(paths, options, most, executor, cache)


def parallel_pays(paths: Sequence[str], jobs: int) -> bool:
    """Whether reading ``paths`` in ``jobs`` fresh worker processes beats reading them here.

    The reading they hold (``SECONDS_PER_BYTE`` of each file's size) shared by ``jobs``
    processes must save more than the workers' start (``START_SECONDS``) and the arrays' trip
    back (``SECONDS_PER_FILE`` each).
    """
    work = 0.0
    for path in paths:
        per_byte = SECONDS_PER_BYTE.get(os.path.splitext(path)[1].lower(), 0.0)
        work += per_byte * _size([path])
    saved = work * (1.0 - 1.0 / jobs) - SECONDS_PER_FILE * len(paths)
    return jobs > 1 and saved > START_SECONDS


def read_task(store: dict, paths: list[str], limits: Limits, step: StepOptions) -> list[tuple]:
    """Read files in a worker process; see ``read_files``.

    Returns one outcome per file, stopping after the first file that cannot be read:
    ``(events, warned, read)``, where ``events`` are the budget checks made, each as
    ``(warnings raised before it, method name, arguments)``, ``warned`` the warnings raised as
    ``(category, message)``, and ``read`` a ``FileRead`` or, for a file that cannot be read,
    ``(error class, path, reason)``.
    """
    out = []
    for path in paths:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            budget = _Recorder(limits, caught)
            try:
                result = _read(path, budget, step)
            except MeshcheckError as exc:
                result = (type(exc), exc.path, exc.reason)
        if isinstance(result, FileRead):
            result = _narrow(result)
        out.append((budget.events, [_portable(w) for w in caught], result))
        if not isinstance(result, FileRead):
            break
    return out


def _narrow(read: FileRead) -> FileRead:
    """The same values in fewer bytes for the trip to the parent: float32 vertices when every
    coordinate is one (an STL's always are), int32 faces when the indices fit."""
    geometries = []
    for v, f, closed in read.geometries:
        narrow = v.astype(np.float32)
        if np.array_equal(narrow, v):  # compared as float64: exact, signed zeros kept
            v = narrow
        if len(v) <= np.iinfo(np.int32).max:
            f = f.astype(np.int32)
        geometries.append((v, f, closed))
    return dataclasses.replace(read, geometries=geometries)


def _widen(read: FileRead) -> FileRead:
    """``_narrow`` undone: float64 vertices and int64 faces, bit for bit a serial read's."""
    geometries = [
        (v.astype(np.float64), f.astype(np.int64), closed) for v, f, closed in read.geometries
    ]
    return dataclasses.replace(read, geometries=geometries)


def _replay(path: str, budget: Budget, outcome: tuple) -> FileRead:
    """A worker's outcome for one file, with its budget checks and warnings redone here."""
    events, warned, result = outcome
    shown = 0
    for before, method, args in events:
        _warn_again(warned[shown:before])
        shown = before
        getattr(budget, method)(*args)
    _warn_again(warned[shown:])
    if not isinstance(result, FileRead):
        kind, where, reason = result
        raise kind(where, reason)
    budget.take(path, result.triangles, len(result.items))
    return _widen(result)


class _Recorder(Budget):
    """An empty budget that notes every check made of it, and how many warnings came before."""

    def __init__(self, limits: Limits, caught: list):
        super().__init__(limits)
        self.caught = caught
        self.events: list[tuple[int, str, tuple]] = []

    def check_triangles(self, path, count, what="triangles"):
        self.events.append((len(self.caught), "check_triangles", (path, count, what)))
        super().check_triangles(path, count, what)

    def check_parts(self, path, count, what="parts"):
        self.events.append((len(self.caught), "check_parts", (path, count, what)))
        super().check_parts(path, count, what)


def _portable(w: warnings.WarningMessage) -> tuple[type[Warning], str]:
    """A warning as (category, text), the category one the parent process can unpickle."""
    category = w.category
    if not (issubclass(category, MeshcheckWarning) or category.__module__ == "builtins"):
        return UserWarning, f"{category.__name__}: {w.message}"
    return category, str(w.message)


def _warn_again(warned: list[tuple[type[Warning], str]]) -> None:
    for category, text in warned:
        warnings.warn(category(text), stacklevel=4)


def _size(paths) -> int:
    """Bytes of the files (0 for one that cannot be stat'ed: reading it will say why)."""
    total = 0
    for path in paths:
        try:
            total += os.stat(path).st_size
        except OSError:
            pass
    return total
