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
4. ``decide_on_brep`` decides the pairs of STEP solids on their exact B-rep, once per pair of
   products and relative placement (the meshes only filter out pairs clear by a margin), and
   ``verify_pairs`` decides the rest on the real meshes;
5. ``approve`` marks approved findings, in one place.

Every pair is decided with its own tolerance (``tolerances.pair_tolerances``) unless the user
gave one. A run of clash tests (``Settings.tests``) runs the stages once for all its tests, each
test judging the verdicts of its pairs (``verify.clash_tests``).
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
from .load import Body, Limits, load_assembly, local_geometries
from .load.limits import check_candidate_pairs
from .load.robot import Mechanism
from .outcome import CheckResult
from .progress import Progress
from .results import Finding, Part
from .settings import Settings
from .sweep import audit_srdf, mechanism_pieces, sweep_bodies, with_adjacent_approvals
from .tolerances import part_sizes
from .units import DEFAULT_UNIT
from .verify import verify_pairs
from .verify.brep import decide_on_brep, largest_reach_margin, reach_margin, warn_unconfirmed
from .verify.clash_tests import (
    held_by_any,
    judged,
    largest_clearance,
    largest_tolerance,
    pair_clearances,
    verify_plans,
    widest_tolerances,
)
from .verify.duplicates import duplicate_findings, duplicate_sets, without_duplicate_pairs
from .verify.elements import with_elements
from .verify.shells import warn_nothing_to_compare, warn_overlapping_shells


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
        ``use_cache``, ``jobs``, ``tests`` (clash tests: ``config.ClashTest`` or
        ``"NAME:A:B[:KEY=VALUE]..."`` as ``--test`` takes them).

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
                assembly = load_assembly(
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
            bodies, mechanisms = assembly.bodies, assembly.mechanisms
            settings = with_adjacent_approvals(settings, bodies, mechanisms)  # adjacent links
            result = check_bodies(
                bodies, settings, executor=executor, mechanisms=mechanisms, caches=caches
            )
    finally:
        caught = _reissue(caught)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeshcheckWarning)]
    return dataclasses.replace(result, warnings=[*result.warnings, *messages])


def check_bodies(
    bodies: Sequence[Body],
    settings: Settings | None = None,
    *,
    executor: Executor | None = None,
    mechanisms: Sequence[Mechanism] = (),
    caches: Caches | None = None,
    **fields,
) -> CheckResult:
    """Run the check on bodies already loaded; see ``check``.

    ``settings`` defaults to ``Settings(**fields)`` (there ``cache_dir=None`` means no cache).
    ``executor`` is the run's (left open); default: one for ``settings.jobs`` and
    ``settings.scheduler``, closed at the end. ``mechanisms`` are the robots among the bodies
    (``load.Assembly.mechanisms``), swept when ``settings.motion.sweep`` is set. ``caches`` are
    the run's (``cache.open_caches``); default: opened here from ``settings.cache_dir``.
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
        diagonal, magnitude = part_sizes(hulls.lower, hulls.upper, [b.is_float32 for b in bodies])
        deflection = np.array([b.deflection for b in bodies], dtype=np.float64)
        pairs = select_pairs(
            hulls, settings, names, diagonal, magnitude, deflection, largest_reach_margin(bodies)
        )
        copies = duplicate_sets(bodies, geometry, tolerance=settings.tolerance)
        pairs = without_duplicate_pairs(pairs, copies, len(bodies))
        check_candidate_pairs(len(pairs), len(bodies))  # budgeted, like triangles
        # Triangles of a part read from CAD lie up to its deflection from the true surface:
        # overlaps and gaps within the two deflections cannot be told apart, so they touch.
        tolerance = widest_tolerances(diagonal, magnitude, pairs, settings, deflection=deflection)
        reach = tolerance + pair_clearances(settings, names, pairs) + reach_margin(bodies, pairs)
        hull_query = query_pairs(hulls, pairs, tolerance=tolerance, depth=False, max_distance=reach)
        near = may_come_within(hull_query, reach)
    pairs_near, tol_near, reach_near = pairs[near], tolerance[near], reach[near]
    with (
        contextlib.nullcontext(executor)
        if executor is not None
        else executor_for(jobs=settings.jobs, scheduler=settings.scheduler)
    ) as executor:
        swept = mechanism_pieces(
            bodies, mechanisms, settings, executor=executor, cache=caches.decompositions
        )
        pieces, owner, piece_count = decompose_parts(
            bodies,
            pairs_near,
            settings,
            executor=executor,
            geometry=geometry,
            cache=caches.decompositions,
            known=swept,
        )
        near_surfaces = surfaces_near(pieces, owner, pairs_near, tol_near, reach_near)
        penetrate = hull_query.status[near] == Status.PENETRATING
        plans = verify_plans(
            settings, names, pairs_near, diagonal, magnitude, deflection=deflection
        )
        verified = []
        for plan in plans:  # one without clash tests; else one per tolerance among the tests
            planned, surfaces = pairs_near[plan.mask], near_surfaces[plan.mask]
            solid_findings, on_meshes, unconfirmed = decide_on_brep(
                bodies, planned, surfaces, plan.settings, executor=executor, cache=caches.verdicts
            )
            findings = verify_pairs(
                bodies,
                planned[on_meshes],
                plan.tolerance[on_meshes],
                surfaces[on_meshes],
                plan.settings,
                executor=executor,
                cache=caches.verdicts,
                hulls_penetrate=penetrate[plan.mask][on_meshes],
            )
            warn_unconfirmed(findings, unconfirmed)
            findings = [*findings, *solid_findings]
            findings = with_elements(bodies, findings, clearance=plan.settings.clearance)
            verified.append(findings)
        sweeps = sweep_bodies(bodies, mechanisms, settings, pieces=swept)
        audit = audit_srdf(bodies, mechanisms, settings, pieces=swept, sweeps=sweeps)
    duplicates = duplicate_findings(bodies, copies, geometry)
    findings = judged(bodies, settings, plans, verified, duplicates, geometry=geometry, names=names)
    findings = approve(
        findings, settings.approvals, dict(zip([b.name for b in bodies], names, strict=True))
    )
    return _result(bodies, findings, settings, pairs, piece_count, sweeps, names, mechanisms, audit)


def _result(
    bodies, findings, settings, pairs, piece_count, sweeps, names, mechanisms=(), audit=None
) -> CheckResult:
    """The run's ``CheckResult``: findings, parts, the candidate pairs, the bodies, the sweeps,
    the pairs each clash test holds, each robot's pose and the SRDF audit."""
    parts = [
        Part(b.name, b.path, len(b.mesh.faces), b.is_closed, int(piece_count[k]))
        for k, b in enumerate(bodies)
    ]
    named = [tuple(sorted((bodies[i].name, bodies[j].name))) for i, j in pairs]
    test_pairs = {
        t.name: [p for p, is_held in zip(named, t.holds(names, pairs), strict=True) if is_held]
        for t in settings.tests
    }
    return CheckResult(
        findings=findings,
        parts=parts,
        settings=settings,
        checked_pairs=named,
        bodies=tuple(bodies),
        units=bodies[0].units if bodies else (settings.units or DEFAULT_UNIT),
        sweeps=sweeps,
        poses=tuple(m.robot_pose() for m in mechanisms),
        audit=audit,
        test_pairs=test_pairs,
    )


# ---------------------------------------------------------------------------------------------
# Stages


def select_pairs(
    hulls: ConvexPack,
    settings: Settings,
    names: Sequence[tuple[str, ...]],
    diagonal: np.ndarray,
    magnitude: np.ndarray,
    deflection: np.ndarray | None = None,
    margin: float = 0.0,
) -> np.ndarray:
    """Part pairs whose boxes come within reach, restricted by the groups rule or the clash
    tests' sides; ``(k, 2)``.

    The boxes grow by the largest tolerance any pair can get (``tolerances``; of any test), the
    largest clearance and ``margin`` (for STEP solids: ``verify.brep.largest_reach_margin``), so
    no pair within its own reach is pruned.
    """
    largest = largest_tolerance(diagonal, magnitude, settings, deflection=deflection)
    reach = largest + (largest_clearance(settings) or 0.0) + margin
    pairs = candidate_pairs(hulls.lower, hulls.upper, margin=reach)
    if settings.groups is not None:
        pairs = pairs[settings.groups.pair_mask(names, pairs)]
    if settings.tests:
        pairs = pairs[held_by_any(settings.tests, names, pairs)]
    return pairs


def may_come_within(result, reach: np.ndarray) -> np.ndarray:
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
    known: dict[int, list[np.ndarray]] | None = None,
) -> tuple[ConvexPack, np.ndarray, np.ndarray]:
    """Convex pieces of the parts of the hull-near ``pairs`` (``(k, 2)``, indices into
    ``bodies``): CoACD's where the cost model says they pay (``decompose.coacd_budgets``), the
    hull elsewhere. CoACD runs on ``executor`` (default: ``settings.jobs`` local processes);
    pieces are kept in ``cache``, the run's decompositions (``decompose.decompose_bodies``).
    Parts in ``known`` (body index -> world pieces: the sweep's, ``sweep.mechanism_pieces``)
    keep those.

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
    known = known or {}
    fresh = [bodies[i] for i in needed if i not in known]
    with Progress("decomposing", len({geometry[id(b.mesh)].digest for b in fresh})) as bar:
        fresh_lists = decompose_bodies(
            fresh,
            threshold=settings.threshold,
            cache=cache,
            jobs=settings.jobs,
            progress=bar,
            time_limit=budgets,
            executor=executor,
            geometry=geometry,
        )
    fresh_pieces = iter(fresh_lists)
    piece_lists = [known[i] if i in known else next(fresh_pieces) for i in needed]
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
    hit = may_come_within(query, reach[row])
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
    for test in settings.tests:
        for side in ("a", "b"):
            patterns = getattr(test.sides, side)
            if not any(matches(p, n) for p in patterns for n in names):
                raise ConfigError(
                    settings.config_path or "--test",
                    f"test {test.name!r}: {side} ({', '.join(map(repr, patterns))}) matches no "
                    "part; " + examples(),
                )
    every = {n for ns in names for n in ns}  # a pattern without wildcards names one part
    for rule in settings.approvals:
        if rule.id is not None:
            continue
        for pattern in (rule.a, rule.b):
            if not any(c in pattern for c in "*?[") and pattern in every:
                continue
            if not any(matches(pattern, n) for n in names):
                warnings.warn(
                    MeshcheckWarning(
                        f"{settings.config_path or 'approvals'}: ignore rule {rule.label} "
                        f"({rule.reason}): {pattern!r} matches no part (a stale approval?)"
                    ),
                    stacklevel=3,
                )
                break


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
