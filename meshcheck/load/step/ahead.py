"""A STEP file read ahead: a worker imports OpenCASCADE and reads the file while this process
imports trimesh, scipy and the pipeline; the load stage takes what it read.

Why
---
A cold check of a small STEP file spends most of its time importing, one import after the other
on one core: trimesh with scipy (0.4-0.5 s of CPU), then OpenCASCADE (0.6-0.8 s), then the read.
When the run may use a second process (``-j 2`` or more, local), the command starts one worker
before it imports the pipeline (``start``): the worker the command's entry point started
before it even imported the command line's modules, when the arguments named a STEP file
(``meshcheck.__main__``), else a new one. The worker imports OpenCASCADE, reads and checks the
file, and makes its ``tessellate.Products``: the products copied, counted at a coarse deflection
and written as BRep text, and the products as read written too, for the exact solids
(``read_task``). A small file's products (the ones the load stage meshes in its own process) it
triangulates too: BRepMesh's triangles, face by face, which need no trimesh. This process
meanwhile imports the rest (and OpenCASCADE, for a large file, whose products it meshes too);
the load stage takes the worker's products (``take``), welds the triangles (or meshes the
products), and the worker stays in the run's pool with OpenCASCADE loaded, for the pairs decided
on the B-rep. The worker forks a twin as soon as OpenCASCADE is loaded (``execute._Worker``):
a second worker with the import made, which the pool keeps in reserve. A small file's pairs are
all theirs to decide: this process does not load OpenCASCADE for them
(``verify.brep._left_to_workers``), and the twin shares them with the worker. A large file's
products are meshed here and in one worker, which welds them with trimesh: this process has
the twin import it (``execute.prepare_twin_early``) once its own OpenCASCADE is loaded, while
the worker still reads and the second core would wait, and the twin takes the worker's place
in the pool.

A run of several STEP files reads the others in the pool once the load stage reaches the
second (``read_in_pool``, from ``files.read_files``): the worker and its twin are in the pool
by then, and each file is ``read_task``'s, as the first was; ``take`` gives each its products.

What it cannot change
---------------------
The worker runs the code ``read.read_step`` runs here on the same bytes, so the products, the
meshes and every report are the same with it or without it (``-j 1`` never reads ahead).
``take`` gives None, and the load stage reads the file itself, whenever the worker did not read
the bytes the load stage read (the file changed, or the path names another file now) with the
same settings, could not read them (the load stage then reports the error as it would have), or
died. A file whose tessellation is in the cache is not read: its worker is stopped (``drop``).

This module imports OpenCASCADE and numpy only (not trimesh), so the worker reads while this
process imports trimesh.
"""

from __future__ import annotations

import hashlib
import os
from typing import TYPE_CHECKING

from ...execute import (
    has_early,
    local_jobs,
    prepare_twin_early,
    start_early,
    stop_early,
    take_early,
)
from ...units import DEFAULT_UNIT, given_units
from ..formats import STEP_EXTENSIONS
from ..limits import Limits, read_file
from .document import read_document
from .tessellate import (
    DEFAULT_ANGULAR_DEFLECTION,
    MAX_STEP_TRIANGLES,
    PREPARE,
    PREPARE_BYTES,
    PREPARE_WELDING,
    Products,
    brep_text,
    estimated_triangles,
    first_instances,
    products,
    triangulated,
)
from .units import mesh_settings

if TYPE_CHECKING:
    from ...execute import Executor
    from ...settings import Settings

#: The task of the worker that reads a file ahead.
READ_TASK = "meshcheck.load.step.ahead:read_task"
#: Files read in the pool (``read_in_pool``) and not taken yet: real path -> ``read_task``'s
#: result.
_READ: dict[str, tuple] = {}
#: Bytes of STEP files read in the pool at once: their products wait in this process until the
#: load stage takes them (a few times their size, triangles included); the files past it are
#: read here, as before.
POOL_READ_BYTES = 32 << 20


def start(paths: list[str], settings: Settings) -> None:
    """Start a worker reading the first STEP file named in ``paths`` (a directory's files are
    not looked for), when the run has a local process besides this one (``-j``); nothing
    otherwise. ``stop`` ends it when the load stage did not take it."""
    if settings.scheduler or local_jobs(settings.jobs) < 2:
        return
    for path in paths:
        if os.path.splitext(path)[1].lower() in STEP_EXTENSIONS and os.path.isfile(path):
            deflection = settings.step_deflection
            options = (  # as the load stage passes them to ``read_step``
                deflection,
                (settings.units or DEFAULT_UNIT) if deflection is not None else None,
                given_units([path], settings.file_units).get(path),
            )
            # The most triangles the load stage may allow the file (less when files read before
            # it took some): the worker meshes a small file only within it.
            budget = min(settings.max_triangles or Limits().max_triangles, MAX_STEP_TRIANGLES)
            try:
                # The worker forks a twin as soon as OpenCASCADE is loaded (``take``).
                # It meshes in as many threads as the run has processes: the others wait.
                threads = local_jobs(settings.jobs)
                start_early(
                    _key(path),
                    READ_TASK,
                    (path, options, budget, threads),
                    prepare=PREPARE,
                    twin=True,
                )
            except OSError:  # gone since, or no process or pipe to be had: the load stage
                pass  # reads it, or says why it cannot
            return


def read_in_pool(
    paths: list[str], options: list[tuple], budget: int, executor: Executor, cache=None
) -> None:
    """Read the STEP files ``paths`` in ``executor``'s pool, ``read_task`` each with its
    ``options`` (as ``start`` makes them), for ``take`` to give their products: the later STEP
    files of a run, which the load stage would read one after the other here. Only files under
    ``PREPARE_BYTES`` (a larger file's products are meshed in the pool already) whose
    tessellation is not in ``cache`` (its entry's file absent), up to ``POOL_READ_BYTES`` in
    all, are read, by the workers the pool has started (the one that read the first file and
    its twin; none started, nothing is read: a fresh worker would import OpenCASCADE first).
    This process takes none: it would import OpenCASCADE for them, which a run of small files
    then never does. A file that cannot be read there is read here when its turn comes, and
    refused then."""
    from ...cache import tessellation_key
    from ...execute import Task

    if not getattr(executor, "started", 0):  # a LocalPool's workers, its reserve's too
        return
    tasks, total = [], 0
    for path, option in zip(paths, options, strict=True):
        try:
            size = os.path.getsize(path)
            if size >= PREPARE_BYTES or os.path.realpath(path) in _READ:
                continue
            if total + size > POOL_READ_BYTES:
                break
            if cache is not None:
                data = read_file(path, Limits())
                _, _, wanted_mm, ratio = mesh_settings(data, *option)
                key = tessellation_key(
                    data, wanted_mm, DEFAULT_ANGULAR_DEFLECTION, default_scale=ratio
                )
                if os.path.exists(cache.path(key)):
                    continue
        except Exception:  # what it is the load stage says when it reads the file
            continue
        tasks.append(Task((path, option, budget), size=size))
        total += size
    if not tasks:
        return
    results = executor.map(READ_TASK, tasks, grow=False)
    for task, result in zip(tasks, results, strict=True):
        if result is not None:
            _READ[os.path.realpath(task.args[0])] = result


def read_task(
    store: dict, path: str, options: tuple, budget: int, threads: int = 1
) -> tuple | None:
    """In the worker: ``path`` read (within the default limits) and made ``Products`` as
    ``read.read_step`` makes them with ``options`` (deflection, its unit and the unit the user
    gave the file), with the products as read written too (``solid_texts``), and, for a file
    the load stage meshes in its own process (below ``PREPARE_BYTES``) whose estimate fits
    ``budget`` triangles, each product triangulated (``triangles``: the load stage only welds
    them), the meshes made in ``threads`` threads (``tessellate.in_parallel``). Returns (the
    bytes' SHA-256, the settings, the products), or None when anything goes wrong: the load
    stage then reads the file itself, and refuses it (or fails: out of memory, a bug) exactly
    as it would have without a worker."""
    try:
        data = read_file(path, Limits())
        _, unit, wanted_mm, ratio = mesh_settings(data, *options)
        angular = DEFAULT_ANGULAR_DEFLECTION
        instances = read_document(data, path)
        read = products(instances, path, wanted_mm, angular, unit, ratio, threads)
        first = first_instances(instances)
        read.solid_texts = {key: brep_text(inst.product) for key, inst in first.items()}
        if len(data) < PREPARE_BYTES and estimated_triangles(read) <= budget:
            read.triangles = triangulated(read, unit, angular, threads)
    except Exception:  # what it was is the load stage's to say, as without a worker
        return None
    settings = (unit, wanted_mm, angular, ratio)
    return hashlib.sha256(data).hexdigest(), settings, read


def take(path: str, data: bytes, settings: tuple, executor: Executor | None) -> Products | None:
    """The products of ``path`` read ahead, when a worker read exactly ``data`` with
    ``settings`` (``(unit, deflection mm, angular, ratio)`` as ``read_step`` has them); None
    otherwise. The worker then joins ``executor``'s pool.

    For a large file (``PREPARE_BYTES``), OpenCASCADE is imported here first, while the worker
    reads: its products are meshed here too, and B-rep pairs decided. A small file's worker
    triangulates it, and this process does not load OpenCASCADE for it: the worker decides its
    B-rep pairs (``verify.brep._left_to_workers``; a product whose triangles weld open is
    meshed here, loading it then)."""
    key = _key(path)
    if not has_early(key):
        return _checked(_READ.pop(os.path.realpath(path), None), data, settings)
    if len(data) >= PREPARE_BYTES:
        import OCP.TopoDS  # noqa: F401

        # Its products are meshed here and in one worker, which welds them with trimesh and
        # scipy (0.4-0.5 s of CPU to import): the worker's twin imports them now, while the
        # worker reads and this process waits, and takes the worker's place in the pool.
        prepare_twin_early(key, PREPARE_WELDING)
    return _checked(take_early(key, executor), data, settings)


def _checked(result: tuple | None, data: bytes, settings: tuple) -> Products | None:
    """The products of ``read_task``'s ``result`` when it read ``data`` with ``settings``."""
    if result is None:
        return None
    digest, made_with, read = result
    if digest != hashlib.sha256(data).hexdigest() or made_with != settings:
        return None
    return read


def drop(path: str) -> None:
    """Stop the worker reading ``path`` ahead, if any: the load stage needs nothing read."""
    _READ.pop(os.path.realpath(path), None)
    stop_early(_key(path))


def stop() -> None:
    """Stop every worker still reading ahead (the run is over, or failed before taking it),
    and forget the files read in the pool that were not taken."""
    _READ.clear()
    stop_early()


def _key(path: str) -> tuple[str, str]:
    return ("step-ahead", os.path.realpath(path))
