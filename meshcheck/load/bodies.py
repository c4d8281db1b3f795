"""Files -> bodies: read every file, place every body in world coordinates and one report unit,
name it, and hand down the robots among them (see the package docstring for the rules)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from .. import units as units_
from ..errors import ConfigError, InputError
from ..mesh import split_shells, warn
from .body import Assembly, Body, mesh_digest
from .files import (
    FileRead,
    StepOptions,
    is_multi,
    read,
    read_files,
)
from .joints import pose_parts
from .limits import (
    IDENTITY,
    Budget,
    Limits,
    box_corners,
    check_placement,
    doubtful_placements,
)
from .paths import named_files
from .sizes import warn_sizes
from .srdf import with_srdf
from .urdf import urdf_mechanism

if TYPE_CHECKING:
    from ..cache import TessellationCache


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
        configuration's ``[[joint]]`` mechanism, posed too (``load.joints``); the SRDF to audit,
        read and given to the URDF robot (``load.srdf``).

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
    files = named_files(paths)
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
    found = [urdf_mechanism(r.robot, bodies, motion) for r in reads if r.robot is not None]
    if motion is not None and motion.joints:  # the [[joint]] mechanism, posed (load.joints)
        bodies, mech = pose_parts(bodies, motion)
        found.append(mech)
    if motion is not None and motion.audit is not None:  # the SRDF to audit, checked
        found = with_srdf(found, motion.audit, budget.limits)
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
    given twice is refused, and implausible sizes warn (``sizes.warn_sizes``)."""
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
    warn_sizes(sizes, report, given)
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
    digests = [mesh_digest(m) for m in meshes]  # each geometry hashed once, however placed
    lower = np.array([v.min(axis=0) for v, _, _ in file_read.geometries]).reshape(-1, 3)
    upper = np.array([v.max(axis=0) for v, _, _ in file_read.geometries]).reshape(-1, 3)
    which = np.array([g for _, g, _ in file_read.items], dtype=np.int64)
    transforms = np.array([placement for _, _, placement in file_read.items]).reshape(-1, 4, 4)
    if factor != 1.0:
        transforms = to_report @ transforms
    names = [f"{path}#{node}" if multi else path for node, _, _ in file_read.items]
    if len(which) == 1:  # one part (a mesh file); stored where it sits, it was checked as read
        doubtful = np.array([not np.array_equal(transforms[0], IDENTITY)])
    else:  # many placements (instances): screened at once, the doubtful checked one by one
        doubtful = doubtful_placements(transforms, lower[which], upper[which], limits)
    for k in np.flatnonzero(doubtful):
        g = which[k]
        check_placement(
            names[k], file_read.geometries[g][0], transforms[k], limits, bounds=(lower[g], upper[g])
        )
    bodies = [
        Body(
            name,
            path,
            meshes[g],
            transform,
            relative_name=f"{rel}#{node}" if multi else rel,
            units=report,
            deflection=file_read.deflection_of(g) * factor,
            is_float32=file_read.is_float32,
            is_rescaled=is_rescaled,
            brep=file_read.solids,
            elements=file_read.elements.get(node, ()),
            source_digest=file_read.source_of(g),
            known_digest=digests[g],
        )
        for name, (node, g, _), transform in zip(names, file_read.items, transforms, strict=True)
    ]
    return bodies, _diagonal(transforms, lower[which], upper[which])


def _diagonal(transforms: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Diagonal of the box around ``n`` boxes placed by ``transforms`` ``(n, 4, 4)``."""
    if len(transforms) == 1 and np.array_equal(transforms[0], IDENTITY):
        return float(np.linalg.norm(upper[0] - lower[0]))
    corners = box_corners(lower[:, None, :], upper[:, None, :])  # (n, 8, 3)
    placed = np.einsum("nij,nkj->nki", transforms[:, :3, :3], corners) + transforms[:, None, :3, 3]
    still = np.all(transforms == IDENTITY, axis=(1, 2))
    placed[still] = corners[still]  # a part stored where it sits: its own box, unmoved
    placed = placed.reshape(-1, 3)
    return float(np.linalg.norm(placed.max(axis=0) - placed.min(axis=0)))


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
