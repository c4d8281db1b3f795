"""The check, stage by stage: load -> broad phase -> hulls -> pieces -> verify -> approve.

Each stage narrows the part pairs the next one looks at:

1. ``candidate_pairs`` on the parts' boxes, grown by the reach (clearance + tolerance), then the
   groups rule;
2. ``near_pairs``: GJK on whole-part convex hulls. A part's mesh lies inside its hull, so pairs
   whose hulls stay beyond the reach are clear, and parts that meet nobody are never decomposed;
3. ``decompose_parts`` then ``surfaces_near``: GJK on the convex pieces of the remaining parts.
   The pieces cover every triangle of their part, so pairs whose pieces stay beyond the reach have
   surfaces beyond the reach: they are clear unless one part is buried inside the other, which the
   verify stage decides with one point per shell;
4. ``verify_pairs`` decides the rest on the real meshes;
5. ``approve`` marks approved findings, in one place.

Every pair is decided with its own tolerance (``settings.pair_tolerances``) unless the user gave
one.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import warnings
from collections.abc import Sequence

import numpy as np

from .cache import Caches, DecompositionCache, open_caches
from .config import Approval, approval_reason
from .decompose import coacd_budgets, decompose_bodies
from .errors import MeshcheckWarning
from .execute import Executor, executor_for
from .geometry import ConvexPack, Status, pack_convex, query_pairs
from .geometry.broadphase import candidate_pairs, group_pairs
from .load import Body, Limits, load_bodies, local_geometries
from .load.limits import check_candidate_pairs
from .progress import Progress
from .results import CheckResult, Finding, Part
from .settings import (
    FLOAT32_ULPS,
    TOLERANCE_FRACTION,
    Settings,
    pair_tolerances,
    part_sizes,
)
from .sweep import with_mechanisms, with_sweeps
from .units import DEFAULT_UNIT
from .verify import verify_pairs
from .verify.brep import confirm_on_brep
from .verify.duplicates import duplicate_findings, duplicate_sets, without_duplicate_pairs
from .verify.patterns import with_patterns
from .verify.shells import warn_nothing_to_compare, warn_overlapping_shells

_EPS32 = float(np.finfo(np.float32).eps)


def check(
    paths: str | os.PathLike | Sequence[str | os.PathLike],
    settings: Settings | None = None,
    *,
    config="auto",
    **options,
) -> CheckResult:
    """Check the parts in ``paths`` for interference, contact and (optionally) clearance.

    Parameters
    ----------
    paths : path or sequence of paths
        Mesh files and directories (every supported mesh file below them). Each body becomes a
        part named by its path, ``PATH#NODE`` inside multi-body files.
    settings : Settings, optional
        Everything the check runs with. When not given, it is built from ``options`` and the
        configuration file, exactly as the command line does (``Settings.from_options``).
    config : "auto", Config, path or None
        Only without ``settings``: ``"auto"`` (default) reads the ``meshcheck.toml`` or
        ``pyproject.toml [tool.meshcheck]`` found from the working directory upward, as the
        command line does; None reads none.
    **options
        Keyword options of ``Settings.from_options``: ``clearance``, ``tolerance``,
        ``threshold``, ``fail_on``, ``approvals``, ``groups``, ``split``, ``units``,
        ``file_units`` (``{"engine.glb": "mm"}``: a file's unit, whatever it declares),
        ``cache_dir`` (default: the user's cache directory, as on the command line),
        ``use_cache``, ``jobs``.

    Returns
    -------
    CheckResult
        With ``passed``/``failed`` as the command line decides them. Its ``warnings`` list the
        MeshcheckWarnings raised on the way, which are also re-issued.

    Raises
    ------
    InputError
        An input cannot be checked.
    ConfigError
        An option or the configuration file is invalid.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    paths = [os.fspath(p) for p in paths]
    if settings is None:
        settings = Settings.from_options(config=config, **options)
    elif options:
        raise TypeError("give either settings or options, not both")

    caught: list[warnings.WarningMessage] = []
    try:
        with (
            warnings.catch_warnings(record=True) as caught,
            executor_for(jobs=settings.jobs, scheduler=settings.scheduler) as executor,
        ):
            warnings.simplefilter("always", MeshcheckWarning)
            caches = open_caches(settings.cache_dir)  # each cache once, the key read once
            with Progress("loading", 0) as bar:
                limits = None
                if settings.max_triangles is not None:
                    limits = Limits(max_triangles=settings.max_triangles)
                bodies = load_bodies(
                    paths,
                    split=settings.split,
                    units=settings.units,
                    file_units=settings.file_units,
                    limits=limits,
                    cache=caches.tessellations,
                    step_deflection=settings.step_deflection,
                    progress=bar.update_total,
                    executor=executor,
                    motion=settings.motion,
                )
            settings = with_mechanisms(bodies, settings)  # robots: adjacent links approved
            result = check_bodies(bodies, settings, executor=executor, caches=caches)
            result = with_sweeps(result, bodies, settings, executor=executor)  # --sweep
    finally:
        caught = _reissue(caught)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeshcheckWarning)]
    return dataclasses.replace(result, warnings=[*result.warnings, *messages])


def check_bodies(
    bodies: Sequence[Body],
    settings: Settings | None = None,
    *,
    executor: Executor | None = None,
    caches: Caches | None = None,
    **fields,
) -> CheckResult:
    """Run the check on bodies already loaded; see ``check``.

    ``settings`` defaults to ``Settings(**fields)`` (there ``cache_dir=None`` means no cache).
    ``executor`` is the run's (left open); default: one for ``settings.jobs`` and
    ``settings.scheduler``, closed at the end. ``caches`` are the run's (``cache.open_caches``);
    default: opened here from ``settings.cache_dir``.
    """
    if settings is None:
        settings = Settings(**fields)
    names = [_names(b) for b in bodies]
    if not settings.split:  # a part's own shells that clash are never a finding: say so
        warn_overlapping_shells(bodies)
    warn_nothing_to_compare(bodies, is_split=settings.split)
    _check_patterns(settings, names)
    if caches is None:
        caches = open_caches(settings.cache_dir)

    geometry = local_geometries(bodies)
    with Progress("comparing hulls", 0):
        hulls = pack_convex(_world_hulls(bodies, geometry), is_hull=True)
        diagonal, magnitude = part_sizes(hulls.lower, hulls.upper)
        magnitude = np.where([b.is_float32 for b in bodies], magnitude, 0.0)  # the float32 floor
        deflection = max((b.deflection for b in bodies), default=0.0)
        pairs = select_pairs(hulls, settings, names, diagonal, magnitude, deflection)
        copies = duplicate_sets(
            bodies, geometry, tolerance=settings.tolerance, fraction=TOLERANCE_FRACTION
        )
        pairs = without_duplicate_pairs(pairs, copies, len(bodies))
        check_candidate_pairs(len(pairs), len(bodies))  # budgeted, like triangles
        tolerance = _tolerances(settings, bodies, diagonal, magnitude, pairs)
        reach = tolerance + (settings.clearance or 0.0)
        hull_query = query_pairs(hulls, pairs, tolerance=tolerance, depth=False, max_distance=reach)
        near = within(hull_query, reach)
    pairs_near, tol_near, reach_near = pairs[near], tolerance[near], reach[near]
    with (
        contextlib.nullcontext(executor)
        if executor is not None
        else executor_for(jobs=settings.jobs, scheduler=settings.scheduler)
    ) as executor:
        pieces, owner, piece_count = decompose_parts(
            bodies,
            pairs_near,
            settings,
            executor=executor,
            geometry=geometry,
            cache=caches.decompositions,
        )
        near_surfaces = surfaces_near(pieces, owner, pairs_near, tol_near, reach_near)
        findings = verify_pairs(
            bodies,
            pairs_near,
            tol_near,
            near_surfaces,
            settings,
            executor=executor,
            cache=caches.verdicts,
            hulls_penetrate=hull_query.status[near] == Status.PENETRATING,
        )
        findings = confirm_on_brep(bodies, findings, settings, cache=caches.verdicts)
    findings = sorted(
        [*duplicate_findings(bodies, copies, geometry), *findings], key=lambda f: (f.a, f.b)
    )
    findings = with_patterns(bodies, findings, geometry, tolerance=settings.tolerance)
    findings = approve(
        findings, settings.approvals, dict(zip([b.name for b in bodies], names, strict=True))
    )
    return _result(bodies, findings, settings, pairs, piece_count)


def _result(bodies, findings, settings, pairs, piece_count) -> CheckResult:
    """The run's ``CheckResult``: findings, parts, the candidate pairs, the bodies."""
    parts = [
        Part(b.name, b.path, len(b.mesh.faces), b.is_closed, int(piece_count[k]))
        for k, b in enumerate(bodies)
    ]
    return CheckResult(
        findings=findings,
        parts=parts,
        settings=settings,
        checked_pairs=[tuple(sorted((bodies[i].name, bodies[j].name))) for i, j in pairs],
        bodies=tuple(bodies),
        units=bodies[0].units if bodies else (settings.units or DEFAULT_UNIT),
    )


# ---------------------------------------------------------------------------------------------
# Stages


def select_pairs(
    hulls: ConvexPack,
    settings: Settings,
    names: Sequence[tuple[str, ...]],
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    deflection: float = 0.0,
) -> np.ndarray:
    """Part pairs whose boxes come within reach, restricted by the groups rule; ``(k, 2)``.

    The boxes grow by the largest tolerance any pair can get, so no pair within its own reach is
    pruned.
    """
    if settings.tolerance is not None:
        largest = settings.tolerance
    elif len(diagonal):
        largest = float(
            max(TOLERANCE_FRACTION * diagonal.max(), FLOAT32_ULPS * _EPS32 * magnitude.max())
        )
    else:
        largest = 0.0
    largest = max(largest, 2.0 * deflection)
    pairs = candidate_pairs(hulls.lower, hulls.upper, margin=largest + (settings.clearance or 0.0))
    if settings.groups is not None:
        pairs = pairs[settings.groups.pair_mask(names, pairs)]
    return pairs


def within(result, reach: np.ndarray) -> np.ndarray:
    """Mask of the pairs of a ``query_pairs`` answer that may come within ``reach``: every pair
    not proven separated beyond it."""
    return (result.status != Status.SEPARATED) | (result.distance <= reach)


#: Environment variable for tests and benchmarks: CoACD on every part that meets another, open
#: or closed, each with at most this many seconds, whatever the cost model says
#: (``decompose.coacd_budgets``).
BUDGET_VARIABLE = "MESHCHECK_COACD_BUDGET"


def decompose_parts(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    geometry: dict | None = None,
    cache: DecompositionCache | None = None,
) -> tuple[ConvexPack, np.ndarray, np.ndarray]:
    """Convex pieces of the parts of the hull-near ``pairs`` (``(k, 2)``, indices into
    ``bodies``): CoACD's where the cost model says they pay (``decompose.coacd_budgets``), the
    hull elsewhere. CoACD runs on ``executor`` (default: ``settings.jobs`` local processes);
    pieces are kept in ``cache``, the run's decompositions (``decompose.decompose_bodies``).

    Returns
    -------
    pieces : ConvexPack
        The pieces of all needed parts, world coordinates, grouped by part.
    owner : (p,) int64
        The part index of each piece.
    count : (n,) int64
        Pieces per part; 0 for parts not needed.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    needed = np.unique(pairs)
    chosen = [bodies[i] for i in needed]
    geometry = local_geometries(chosen) if geometry is None else geometry
    rank = np.full(len(bodies), -1, dtype=np.int64)
    rank[needed] = np.arange(len(needed))
    forced = os.environ.get(BUDGET_VARIABLE)
    budgets = coacd_budgets(
        chosen, rank[pairs], geometry=geometry, forced=float(forced) if forced else None
    )
    with Progress("decomposing", len({geometry[id(b.mesh)].digest for b in chosen})) as bar:
        piece_lists = decompose_bodies(
            chosen,
            threshold=settings.threshold,
            cache=cache,
            jobs=settings.jobs,
            progress=bar,
            time_limit=budgets,
            executor=executor,
            geometry=geometry,
        )
    count = np.zeros(len(bodies), dtype=np.int64)
    count[needed] = [len(p) for p in piece_lists]
    owner = np.repeat(needed, count[needed]).astype(np.int64)
    # Pieces may carry extra interior points (triangle cover); a support scan over a superset of
    # the hull's vertices is still exact, so Qhull need not run again.
    pieces = pack_convex([p for plist in piece_lists for p in plist], is_hull=True)
    return pieces, owner, count


def surfaces_near(
    pieces: ConvexPack,
    owner: np.ndarray,
    pairs: np.ndarray,
    tolerance: np.ndarray,
    reach: np.ndarray,
) -> np.ndarray:
    """Which part ``pairs`` have a piece pair within their ``reach`` (or undecided), ``(k,)`` bool.

    A part pair without one has surfaces beyond its reach.
    """
    if len(pairs) == 0:
        return np.zeros(0, dtype=bool)
    # Pieces are grouped by part (``decompose_parts``): test each pair's pieces against each
    # other, rather than sweeping every piece of the assembly.
    parts = int(max(owner.max(initial=-1), pairs.max())) + 1
    count = np.bincount(owner, minlength=parts)
    first = np.searchsorted(owner, np.arange(parts), side="left")
    if np.any(owner[1:] < owner[:-1]):
        raise ValueError("pieces must be grouped by part, in part order")
    piece_pairs, row = group_pairs(
        pieces.lower, pieces.upper, first, count, pairs, np.asarray(reach, dtype=np.float64)
    )
    query = query_pairs(
        pieces, piece_pairs, tolerance=tolerance[row], depth=False, max_distance=reach[row]
    )
    hit = within(query, reach[row])
    out = np.zeros(len(pairs), dtype=bool)
    out[row[hit]] = True
    return out


def approve(
    findings: Sequence[Finding],
    approvals: Sequence[Approval],
    names: dict[str, tuple[str, ...]],
) -> list[Finding]:
    """The findings with the reason of the approval that applies to each (``approval_reason``).

    ``names`` maps each part's name to all its names (full and relative) for pattern matching.
    """
    return [
        dataclasses.replace(
            f, approval_reason=approval_reason(approvals, names[f.a], names[f.b], f.id)
        )
        for f in findings
    ]


# ---------------------------------------------------------------------------------------------
# Helpers


def _reissue(caught: list) -> list:
    """Re-issue recorded warnings outside the recorder, so callers' filters (and the CLI) see
    them as usual; a message said twice (one file's problem met by two stages) is said once."""
    first: dict = {}
    for w in caught:
        first.setdefault((w.category, str(w.message)), w)
    for w in first.values():
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    return list(first.values())


def _names(body: Body) -> tuple[str, ...]:
    """The names patterns are matched against: the full name, then the relative one."""
    relative = body.relative_name
    return (body.name,) if relative == body.name else (body.name, relative)


def _check_patterns(settings: Settings, names: Sequence[tuple[str, ...]]) -> None:
    """Refuse a groups side that matches no part; warn about approvals that match no part.

    A check restricted to a group that matches nothing would check nothing and pass.
    """
    from .config import matches
    from .errors import ConfigError

    def examples() -> str:
        shown = ", ".join(repr(n[-1]) for n in names[:3])
        return f"parts are named like {shown}" + (" ..." if len(names) > 3 else "")

    if settings.groups is not None:
        for side in ("a", "b"):
            patterns = getattr(settings.groups, side)
            if not any(matches(p, n) for p in patterns for n in names):
                where = settings.config_path or "groups"
                raise ConfigError(
                    where,
                    f"groups.{side} ({', '.join(map(repr, patterns))}) matches no part; "
                    + examples(),
                )
    for rule in settings.approvals:
        if rule.id is not None:
            continue
        for pattern in (rule.a, rule.b):
            if not any(matches(pattern, n) for n in names):
                warnings.warn(
                    MeshcheckWarning(
                        f"{settings.config_path or 'approvals'}: ignore rule {rule.label} "
                        f"({rule.reason}): {pattern!r} matches no part (a stale approval?)"
                    ),
                    stacklevel=3,
                )
                break


def _tolerances(
    settings: Settings,
    bodies: Sequence[Body],
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    pairs: np.ndarray,
) -> np.ndarray:
    """The touching tolerance of each pair: the user's, or the pair's own, and never below the
    sum of the two parts' tessellation deflections."""
    if settings.tolerance is not None:
        tol = np.full(len(pairs), settings.tolerance)
    else:
        tol = pair_tolerances(diagonal, magnitude, pairs)
    # Triangles of a part read from CAD lie up to its deflection from the true surface: overlaps
    # and gaps within the two deflections cannot be told apart, so they count as touching.
    deflection = np.array([b.deflection for b in bodies], dtype=np.float64)
    return np.maximum(tol, deflection[pairs[:, 0]] + deflection[pairs[:, 1]])


def _world_hulls(bodies: Sequence[Body], geometry: dict) -> list[np.ndarray]:
    """Hull vertices of each body, world coordinates; qhull runs once per distinct geometry.

    Geometry is compared up to translation (``load.local_geometry``), so instances of one
    mesh and copies of one part at other places share a hull.
    """
    from scipy.spatial import ConvexHull, QhullError

    by_mesh: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # id(mesh) -> (local hull, corner)
    by_digest: dict[str, np.ndarray] = {}
    out = []
    for body in bodies:
        if id(body.mesh) not in by_mesh:
            local, _, corner, digest = geometry[id(body.mesh)]
            if digest not in by_digest:
                try:
                    by_digest[digest] = local[np.sort(ConvexHull(local).vertices)]
                except (QhullError, ValueError):  # flat or degenerate: every vertex
                    by_digest[digest] = local
            by_mesh[id(body.mesh)] = (by_digest[digest], corner)
        hull, corner = by_mesh[id(body.mesh)]
        hull = hull + corner
        transform = np.asarray(body.transform, dtype=np.float64)
        if not np.array_equal(transform, np.eye(4)):
            hull = hull @ transform[:3, :3].T + transform[:3, 3]
        out.append(hull)
    return out
