"""Files -> bodies: every body in world coordinates and one report unit, with the name reports use.

Naming
------
Names are a function of the arguments and of each file's content and structure only (never of
hash seeds, random numbers or the order of a dict), so they and the finding IDs built from them
are the same on every run.

- A part's name is the path exactly as given (``plate.stl``).
- A body inside a file that holds several is named ``PATH#NODE``; bodies of one file are listed
  sorted by NODE. NODE is:

  - glTF/GLB: the node's ``name``, else its index in the file's node list; a name an earlier
    node already has gets ``_2``, ``_3``... A node whose mesh has several triangle primitives
    gives one body per primitive, ``NODE/0``, ``NODE/1``... by primitive index.
  - 3MF: the build item's object ``name``, else ``object<ID>``; an object made of components
    gives one body per mesh it reaches, ``ITEM/COMPONENT`` (the component object's ``name``,
    else ``component<k>`` counting from 1); a name used twice gets ``_2``, ``_3``... in build order.
  - OBJ: the ``o``/``g`` name; STL: the ``solid`` name; unnamed ones ``geometry_<k>`` in file
    order (trimesh's names, made unique in file order).
  - STEP: the product name of each solid (``load.step``), repeated instances ``PRODUCT_1``,
    ``PRODUCT_2``...; a STEP part is always ``PATH#PRODUCT``, even alone in its file.

  A geometry instanced by two nodes gives two parts that share one local mesh (``Body.mesh``)
  and differ by ``Body.transform``.
- A directory argument stands for every supported mesh file below it, recursively, sorted by
  relative path, hidden files and folders skipped; each is named ``os.path.join(ARG, RELPATH)``.
- With ``split=True`` a body made of several disconnected shells becomes one part per shell,
  named ``NAME#1``, ``NAME#2``... in the order of each shell's first triangle in the file. A closed
  inward-facing shell (a cavity lining) inside another shell stays with that shell.
- ``Body.relative_name`` is the name relative to its argument: ``RELPATH[#NODE]`` below a
  directory argument, ``basename(PATH)[#NODE]`` for a file argument (for pattern matching).
- Two inputs giving the same part name are an error.

Units
-----
Every body is converted to one report unit (``Body.units``) by a scale folded into
``Body.transform``; ``Body.mesh`` stays in the file's unit. The rule is ``meshcheck.units``'s:
``units`` names the unit of files that declare none and the report unit; without it undeclared
files are millimetres and the report unit is the one all files declare, when all declare the same,
else millimetres. ``file_units`` (``units.UnitRule``: ``--units FILE=UNIT``) give files their
unit whatever they declare, and then count as what those files declare. Files whose sizes differ
by ``MIXED_UNITS_RATIO`` or more raise a warning (likely mixed units), and so does a file whose
size is implausible for mechanical parts (``LARGE_METRES`` across or more, ``SMALL_METRES`` or
less), each suggesting the ``--units FILE=UNIT`` that would make it plausible.

Validation
----------
Every input problem the user can fix is an ``InputError`` (``error: PATH: reason``, one line):
missing or unreadable paths, unknown extensions, empty or truncated files, files or declared
sizes beyond the run's ``Limits`` (checked before reading: file sizes, 3MF entry sizes and
component fan-out, glTF buffers and accessors, STL/PLY/OFF counts, triangles and parts per run),
glTF nodes that do not form a tree, files without triangles (point clouds), NaN or infinite
coordinates, and placements that flatten a part or take its coordinates beyond
``Limits.max_coordinate``. Triangles with a repeated vertex are dropped with a warning; triangles
of zero area with three distinct vertices are kept (they keep a closed surface closed). Meshes
that are not closed are kept. Each of those raises a ``MeshcheckWarning`` whose message starts
with the part name. (A file whose closed shells overlap each other is kept too; the check warns
about it, ``verify.shells``: the test is the verify stage's.)
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .. import units as units_
from ..errors import ConfigError, InputError
from ..mesh import is_closed, split_shells, warn
from .body import Assembly, Body, LocalGeometry, local_geometries, local_geometry, mesh_digest
from .files import (
    SUPPORTED_EXTENSIONS,
    FileRead,
    StepOptions,
    is_multi,
    read,
    read_files,
)
from .joints import pose_parts
from .limits import IDENTITY, Budget, Limits, box_corners, check_placement
from .urdf import urdf_mechanism

if TYPE_CHECKING:
    from ..cache import TessellationCache

__all__ = [
    "SUPPORTED_EXTENSIONS",
    "Assembly",
    "Body",
    "Limits",
    "LocalGeometry",
    "expand_paths",
    "is_closed",
    "load_assembly",
    "load_bodies",
    "load_file",
    "local_geometries",
    "local_geometry",
    "mesh_digest",
    "split_body",
    "split_shells",
]

#: Files whose bounding-box diagonals differ by this factor or more get a "mixed units?" warning:
#: a metre file among millimetre ones is 1000 times off, and parts of one machine rarely differ
#: by more than a few hundred times (a 1 m frame and its 2 mm pins).
MIXED_UNITS_RATIO = 500.0
#: ... and by this factor or more when the two files are read in different units (a glTF, in
#: metres by its specification, beside a millimetre STL): a glTF exported in millimetres is 1000
#: times too large, and comes out 100 to 500 times the size of a part a few times larger.
MIXED_DECLARED_RATIO = 100.0
#: A file this many metres across or more warns: mechanical assemblies are not hundreds of
#: metres across (a 0.74 m engine in a millimetre glTF reads as 743 m).
LARGE_METRES = 100.0
#: A file this many metres across or less warns: a part of micrometres is a file in metres (or
#: inches) read in millimetres (a 20 mm bolt written in metres reads as 0.02 mm).
SMALL_METRES = 1e-4
#: Units a size warning may suggest, in this order: the first that makes the file between
#: ``PLAUSIBLE_METRES`` across.
SUGGESTED_UNITS = ("mm", "m", "in", "cm")
PLAUSIBLE_METRES = (1e-3, 10.0)

# --------------------------------------------------------------------------------------------
# Paths


def expand_paths(paths: Iterable[str]) -> list[str]:
    """Replace each directory in ``paths`` by the supported mesh files below it.

    Parameters
    ----------
    paths : iterable of str
        Files and directories, as the user gave them.

    Returns
    -------
    files : list of str
        Files in argument order; a directory's files sorted by relative path and joined to it.

    Raises
    ------
    InputError
        A path does not exist, or a directory holds no supported mesh file.
    """
    return [path for path, _ in _expand(paths)]


def _expand(paths: Iterable[str]) -> list[tuple[str, str]]:
    """(file, name relative to its argument) of every file the arguments stand for."""
    files: list[tuple[str, str]] = []
    for path in paths:
        if os.path.isdir(path):
            found = sorted(_walk_meshes(path))
            if not found:
                exts = ", ".join(SUPPORTED_EXTENSIONS)
                raise InputError(path, f"directory holds no mesh files ({exts})")
            files.extend((os.path.join(path, rel), rel) for rel in found)
        elif os.path.exists(path):
            files.append((path, os.path.basename(path) or path))
        else:
            raise InputError(path, "no such file or directory")
    return files


def _walk_meshes(root: str) -> list[str]:
    """Relative paths of supported mesh files below ``root``, skipping hidden entries."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
        rel_dir = os.path.relpath(dirpath, root)
        for name in filenames:
            ext = os.path.splitext(name)[1].lower()
            if name.startswith(".") or ext not in SUPPORTED_EXTENSIONS:
                continue
            out.append(name if rel_dir == os.curdir else os.path.join(rel_dir, name))
    return out


# --------------------------------------------------------------------------------------------
# Loading


def load_bodies(paths: Sequence[str], **options) -> list[Body]:
    """The bodies of ``load_assembly(paths, **options)``."""
    return load_assembly(paths, **options).bodies


def load_assembly(
    paths: Sequence[str],
    *,
    split: bool = False,
    units: str | None = None,
    file_units: Sequence[units_.UnitRule] = (),
    limits: Limits | None = None,
    cache: TessellationCache | None = None,
    step_deflection: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    executor=None,
    parallel: bool | None = None,
    motion=None,
) -> Assembly:
    """Load every body of every file, in world coordinates and one report unit, and the robots
    among them.

    Parameters
    ----------
    paths : sequence of str
        Mesh files and directories, as the user gave them.
    split : bool
        Make every disconnected shell of a body its own part (cavity linings stay with the
        shell around them).
    units : str, optional
        Unit of the files that declare none, and the report unit (``meshcheck.units``).
    file_units : sequence of units.UnitRule, optional
        Units of the files they name, whatever those declare (the last rule naming a file wins).
        A rule from the command line (``source`` None) that names no file is an error; one from
        a configuration file, a warning.
    limits : Limits, optional
        Budgets for the run; default ``Limits()``.
    cache : cache.TessellationCache, optional
        The run's STEP tessellations (``cache.open_caches``); None: not cached.
    step_deflection : float, optional
        Tessellation tolerance for STEP files, in ``units`` (default millimetres); default
        ``step.DEFAULT_DEFLECTION_MM``.
    progress : callable, optional
        Called as ``progress(done, total)`` as files are read, counting files.
    executor : execute.Executor, optional
        The run's executor: with local worker processes, many mesh files are read there
        (``files.read_files``); the bodies, names, warnings and errors are the same either way.
    parallel : bool, optional
        Read in the executor's processes: True always, False never, None (default) when it pays
        (``files.parallel_pays``).
    motion : motion.Motion, optional
        The pose URDF robots are placed at and where their packages are (``load.urdf``); the
        configuration's ``[[joint]]`` mechanism, posed too (``load.joints``).

    Returns
    -------
    Assembly
        The bodies in the order of ``paths``, bodies of one file sorted by node name, every
        ``Body.units`` the report unit; the mechanisms of the URDF robots and of the
        configuration's ``[[joint]]`` tables, the latter posed.

    Raises
    ------
    InputError
        An input cannot be checked; see the module docstring.
    ConfigError
        ``units`` is not a known unit; a command-line ``file_units`` rule names no input file
        or a URDF robot (``_given_units``).
    """
    units = _checked_unit(units)
    budget = Budget(limits or Limits())
    files = _expand(paths)
    given = _given_units([path for path, _ in files], file_units)
    reads = read_files(
        [path for path, _ in files],
        budget,
        StepOptions(step_deflection, units, motion, tuple(sorted(given.items()))),
        cache=cache,
        executor=executor,
        progress=progress,
        parallel=parallel,
    )
    declared = [given.get(path, r.declared) for (path, _), r in zip(files, reads, strict=True)]
    report = units_.report_unit(declared, units)
    bodies = _placed_bodies(files, reads, report, units, budget.limits, split=split, given=given)
    found = [urdf_mechanism(r.robot, bodies) for r in reads if r.robot is not None]
    if motion is not None and motion.joints:  # the [[joint]] mechanism, posed (load.joints)
        bodies, mech = pose_parts(bodies, motion)
        found.append(mech)
    return Assembly(bodies, tuple(found))


def _checked_unit(units: str | None) -> str | None:
    """The canonical name of ``units`` (None stays None); ConfigError for an unknown unit."""
    if units is None:
        return None
    try:
        return units_.unit_name(units)
    except ValueError as exc:
        raise ConfigError(None, str(exc)) from None


def _given_units(paths: list[str], rules: Sequence[units_.UnitRule]) -> dict[str, str]:
    """The unit the user gave each file (``units.given_units``), after refusing a command-line
    rule that names no input file or names a URDF file, and warning about a configuration rule
    that names none."""
    for rule in units_.unmatched_rules(paths, rules):
        if rule.source is None:
            shown = ", ".join(paths[:3]) + (" ..." if len(paths) > 3 else "")
            raise ConfigError(
                rule.pattern, f"--units: names no input file (the inputs are {shown})"
            )
        warn(rule.source, f"[units] {rule.pattern!r} names no input file (a stale entry?)")
    given = units_.given_units(paths, rules)
    for path in given:
        if os.path.splitext(path)[1].lower() in (".urdf",):
            raise ConfigError(
                path,
                "a URDF robot takes no unit (--units, [units]): it is in metres (ROS); give its "
                "meshes' unit with their scale attribute",
            )
    return given


def _placed_bodies(files, reads, report, units, limits, *, split: bool, given) -> list[Body]:
    """Every file's bodies placed in the report unit, split into shells when asked; a name
    given twice is refused, and implausible sizes warn (``_warn_sizes``)."""
    bodies: list[Body] = []
    seen: set[str] = set()
    sizes = []
    for (path, rel), file_read in zip(files, reads, strict=True):
        file_bodies, diagonal = _place(
            path, rel, file_read, report, units, limits, given=given.get(path)
        )
        read_in = given.get(path) or file_read.declared or units or units_.DEFAULT_UNIT
        sizes.append((diagonal, path, read_in))
        for body in file_bodies:
            for part in split_body(body) if split else [body]:
                if part.name in seen:
                    raise InputError(part.name, "given more than once")
                seen.add(part.name)
                bodies.append(part)
    _warn_sizes(sizes, report, given)
    return bodies


def load_file(path: str, *, units: str | None = None, limits: Limits | None = None) -> list[Body]:
    """Load the bodies of one mesh file; raise ``InputError`` naming the file when it is unusable.

    Parameters
    ----------
    path : str
        A mesh file with one of ``SUPPORTED_EXTENSIONS``.
    units, limits
        As for ``load_bodies``.

    Returns
    -------
    bodies : list of Body
        One body (named ``path``) or, when the file holds several, one per node (``path#NODE``),
        sorted by node name.
    """
    units = None if units is None else units_.unit_name(units)
    budget = Budget(limits or Limits())
    file_read = read(path, budget, StepOptions(None, units))
    report = units_.report_unit([file_read.declared], units)
    return _place(path, os.path.basename(path), file_read, report, units, budget.limits)[0]


def _place(
    path: str,
    rel: str,
    file_read: FileRead,
    report: str,
    units: str | None,
    limits: Limits,
    *,
    given: str | None = None,
) -> tuple[list[Body], float]:
    """Bodies of one file, placed in world coordinates in the report unit (the file's unit is
    ``given`` when the user gave one), and the diagonal of their bounding box."""
    read_as = file_read.declared or units or units_.DEFAULT_UNIT
    file_unit = given or read_as
    is_rescaled = units_.METRES[file_unit] != units_.METRES[read_as]
    factor = units_.scale(file_unit, report)
    to_report = np.diag([factor, factor, factor, 1.0])
    multi = is_multi(path, file_read.items)
    meshes = file_read.meshes()
    bounds = [(v.min(axis=0), v.max(axis=0)) for v, _, _ in file_read.geometries]
    bodies, corners = [], []
    for node, g, placement in file_read.items:
        name = f"{path}#{node}" if multi else path
        transform = placement if factor == 1.0 else to_report @ placement
        check_placement(name, file_read.geometries[g][0], transform, limits, bounds=bounds[g])
        if np.array_equal(transform, IDENTITY):
            corners.extend(bounds[g])
        else:
            corners.append(box_corners(*bounds[g]) @ transform[:3, :3].T + transform[:3, 3])
        body = Body(
            name,
            path,
            meshes[g],
            transform,
            relative_name=f"{rel}#{node}" if multi else rel,
            units=report,
            deflection=file_read.deflection * factor,
            is_float32=file_read.is_float32,
            is_rescaled=is_rescaled,
            brep=file_read.solids,
        )
        bodies.append(body)
    corners = np.vstack(corners)
    return bodies, float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))


def _warn_sizes(sizes: list[tuple[float, str, str]], report: str, given: dict) -> None:
    """Warn about files of implausible size (``LARGE_METRES``, ``SMALL_METRES``), then about
    mixed units (``_warn_mixed_units``); never about a file whose unit the user gave.

    Parameters
    ----------
    sizes : list of (float, str, str)
        Each file's diagonal (report units), path, and the unit its lengths were read in.
    """
    warned = set()
    for diagonal, path, unit in sizes:
        metres = diagonal * units_.METRES[report]
        if path in given or diagonal <= 0.0 or SMALL_METRES < metres < LARGE_METRES:
            continue
        what = "hundreds of metres" if metres >= LARGE_METRES else "micrometres"
        message = (
            f"is {diagonal:.4g} {report} across, read in {unit}: {what} across is implausible "
            "for mechanical parts"
        )
        warn(path, message + _suggestion(path, metres, unit))
        warned.add(path)
    _warn_mixed_units([s for s in sizes if s[1] not in warned and s[1] not in given], report)


def _suggestion(path: str, metres: float, unit: str) -> str:
    """``; if it is in mm, give --units PATH=mm``: the first of ``SUGGESTED_UNITS`` that makes
    a file of ``metres`` read in ``unit`` plausible, or ``""``."""
    low, high = PLAUSIBLE_METRES
    for other in SUGGESTED_UNITS:
        size = metres * units_.METRES[other] / units_.METRES[unit]
        if other != unit and low <= size <= high:
            return f"; if the file is in {other}, give --units {path}={other}"
    return ""


def _warn_mixed_units(sizes: list[tuple[float, str, str]], report: str) -> None:
    """Warn when the largest file is ``MIXED_UNITS_RATIO`` times the smallest or more
    (``MIXED_DECLARED_RATIO`` when the two are read in different units)."""
    sizes = [s for s in sizes if s[0] > 0.0]
    if len(sizes) < 2:
        return
    small, big = min(sizes), max(sizes)
    ratio = MIXED_UNITS_RATIO if small[2] == big[2] else MIXED_DECLARED_RATIO
    if big[0] >= ratio * small[0]:
        units = f"read in {big[2]} and {small[2]}" if small[2] != big[2] else f"both {big[2]}"
        warn(
            big[1],
            f"is {big[0] / small[0]:.0f} times the size of {small[1]} "
            f"({big[0]:.4g} against {small[0]:.4g} {report} across, {units}): mixed units? "
            "(files that declare no unit are read in --units, default mm; give a file's own "
            "unit with --units FILE=UNIT)",
        )


# --------------------------------------------------------------------------------------------
# Splitting bodies into shells


def split_body(body: Body) -> list[Body]:
    """One body per disconnected shell of ``body`` (see ``split_shells``), named ``NAME#k``."""
    shells = split_shells(body.mesh)
    if len(shells) == 1:
        return [body]
    return [
        Body(
            f"{body.name}#{k}",
            body.path,
            shell,
            body.transform,
            relative_name=f"{body.relative_name}#{k}",
            units=body.units,
            deflection=body.deflection,
            is_float32=body.is_float32,
            is_rescaled=body.is_rescaled,
        )
        for k, shell in enumerate(shells, start=1)
    ]
