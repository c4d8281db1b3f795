"""The check, stage by stage: load -> broad phase -> hulls -> pieces -> verify -> approve.

Each stage narrows the part pairs the next one looks at:

1. ``candidate_pairs`` on the parts' boxes, grown by the reach (clearance + tolerance), then the
   groups rule;
2. ``near_pairs``: GJK on whole-part convex hulls (one hull per distinct geometry, placed at
   each part). A part's mesh lies inside its hull, so pairs whose hulls stay beyond the reach are
   clear, and parts that meet nobody are never decomposed;
3. ``pair_classes``: the remaining pairs grouped into classes, one per pair of geometries at one
   placement in the pair's own frame (``verify.classes``); from here on the work is per class;
4. ``decompose_parts`` then ``surfaces_near``: GJK on the convex pieces of each class's two
   geometries, placed in the class's frame. The pieces cover every triangle of their part, so
   classes whose pieces stay beyond the reach have surfaces beyond the reach: they are clear
   unless one part is buried inside the other, which the verify stage decides with one point
   per shell;
5. ``decide_on_brep`` decides the pairs of STEP solids on their exact B-rep, once per pair of
   products and relative placement (the meshes only filter out pairs clear by a margin), and
   ``verify_classes`` decides each class of the rest on the real meshes, once, and moves its
   verdict to each of its pairs;
6. ``approve`` marks approved findings, in one place.

Every pair is decided with its own tolerance (``tolerances.pair_tolerances``) unless the user
gave one. A run of clash tests (``Settings.tests``) runs the stages once for all its tests, each
test judging the verdicts of its pairs (``verify.clash_tests``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import warnings
from collections.abc import Sequence

import numpy as np

from .cache import Caches, DecompositionCache, open_caches
from .config import Approval, approval_reason
from .decompose import coacd_budgets, decompose_shapes
from .errors import MeshcheckWarning
from .execute import Executor, executor_for
from .geometry import ConvexPack, Status, pack_convex, place_packs, query_pairs, support_points
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
from .verify import verify_classes
from .verify.brep import (
    decide_on_brep,
    largest_reach_margin,
    prepare_workers,
    reach_margin,
    warn_unconfirmed,
)
from .verify.clash_tests import (
    held_by_any,
    judged,
    largest_clearance,
    largest_tolerance,
    pair_clearances,
    verify_plans,
    widest_tolerances,
)
from .verify.classes import PairClasses, pair_classes
from .verify.duplicates import duplicate_findings, duplicate_sets
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
            prepare_workers(executor, paths)  # OpenCASCADE loads while STEP files are read
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

    @functools.cache
    def warn_of_parts() -> None:
        """What the check says of the parts alone, once: a part's own shells that clash are
        never a finding, and one part is compared with nothing. The B-rep stage calls it
        (``decide_on_brep``'s ``meanwhile``) while its workers decide the first pairs, which
        this check of meshes does not need."""
        if not settings.split:
            warn_overlapping_shells(bodies)
        warn_nothing_to_compare(bodies, is_split=settings.split)

    _check_patterns(settings, names)
    if caches is None:
        caches = open_caches(settings.cache_dir)

    geometry = local_geometries(bodies)
    with Progress("comparing hulls", 0):
        hulls = _world_hulls(bodies, geometry)
        diagonal, magnitude = part_sizes(hulls.lower, hulls.upper, [b.is_float32 for b in bodies])
        deflection = np.array([b.deflection for b in bodies], dtype=np.float64)
        copies = duplicate_sets(bodies, geometry, tolerance=settings.tolerance)
        pairs = select_pairs(
            hulls,
            settings,
            names,
            diagonal,
            magnitude,
            deflection,
            largest_reach_margin(bodies),
            copies=copies,
        )
        check_candidate_pairs(len(pairs), len(bodies))  # budgeted, like triangles
        # Triangles of a part read from CAD lie up to its deflection from the true surface:
        # overlaps and gaps within the two deflections cannot be told apart, so they touch.
        tolerance = widest_tolerances(diagonal, magnitude, pairs, settings, deflection=deflection)
        margin = reach_margin(bodies, pairs)  # pairs of STEP solids: the B-rep's reach
        reach = tolerance + pair_clearances(settings, names, pairs) + margin
        hull_query = query_pairs(hulls, pairs, tolerance=tolerance, depth=False, max_distance=reach)
        near = may_come_within(hull_query, reach)
    pairs_near, tol_near, margin_near = pairs[near], tolerance[near], margin[near]
    penetrate = hull_query.status[near] == Status.PENETRATING
    plans = verify_plans(settings, names, pairs_near, diagonal, magnitude, deflection=deflection)
    # The pairs that remain, grouped into classes (one geometry pair at one placement in the
    # pair's frame): from here on the work is per class, each decided once in its frame. The
    # convex pieces are found for the classes at the widest tolerance; each verification (one
    # without clash tests) groups its own pairs at its own tolerance.
    classes = pair_classes(bodies, pairs_near, tol_near, None, geometry=geometry)
    plan_classes = [
        classes
        if plan.mask.all() and np.array_equal(plan.tolerance, tol_near)
        else pair_classes(bodies, pairs_near[plan.mask], plan.tolerance, None, geometry=geometry)
        for plan in plans
    ]
    with (
        contextlib.nullcontext(executor)
        if executor is not None
        else executor_for(jobs=settings.jobs, scheduler=settings.scheduler)
    ) as executor:
        swept = mechanism_pieces(
            bodies, mechanisms, settings, executor=executor, cache=caches.decompositions
        )
        packs, piece_count = decompose_parts(
            bodies,
            classes,
            settings,
            executor=executor,
            geometry=geometry,
            cache=caches.decompositions,
            known=swept,
        )
        verified = []
        for plan, found in zip(plans, plan_classes, strict=True):
            class_margin = np.zeros(len(found))
            np.maximum.at(class_margin, found.label, margin_near[plan.mask])
            apart = ~surfaces_near(packs, found, plan.settings.clearance, class_margin)
            planned, surfaces = pairs_near[plan.mask], ~apart[found.label]
            solid_findings, on_meshes, unconfirmed = decide_on_brep(
                bodies,
                planned,
                surfaces,
                plan.settings,
                executor=executor,
                cache=caches.verdicts,
                meanwhile=warn_of_parts,
            )
            if on_meshes.all():
                found = dataclasses.replace(found, surfaces_apart=apart)
            else:  # the pairs of STEP solids decided on the B-rep leave their classes
                found = pair_classes(
                    bodies,
                    planned[on_meshes],
                    plan.tolerance[on_meshes],
                    ~surfaces[on_meshes],
                    geometry=geometry,
                )
            findings = verify_classes(
                bodies,
                found,
                plan.settings,
                executor=executor,
                cache=caches.verdicts,
                hulls_penetrate=penetrate[plan.mask][on_meshes],
            )
            warn_unconfirmed(findings, unconfirmed)
            findings = [*findings, *solid_findings]
            findings = with_elements(bodies, findings, clearance=plan.settings.clearance)
            verified.append(findings)
        warn_of_parts()  # when no plan called it
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
    shape: dict[int, tuple[int, bool]] = {}  # triangles and closedness, once per mesh
    for b in bodies:
        if id(b.mesh) not in shape:
            shape[id(b.mesh)] = (len(b.mesh.faces), b.is_closed)
    parts = [
        Part(b.name, b.path, *shape[id(b.mesh)], int(piece_count[k])) for k, b in enumerate(bodies)
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
    *,
    copies: Sequence[Sequence[int]] = (),
) -> np.ndarray:
    """Part pairs whose boxes come within reach, restricted by the groups rule or the clash
    tests' sides; ``(k, 2)``.

    The boxes grow by the largest tolerance any pair can get (``tolerances``; of any test), the
    largest clearance and ``margin`` (for STEP solids: ``verify.brep.largest_reach_margin``), so
    no pair within its own reach is pruned. ``copies`` are the duplicate sets
    (``verify.duplicates``): their pairs are left out (a set is one finding), and the boxes of a
    set's copies, one box, take part in the broad phase once (2,000 coincident copies are one
    box, not two million pairs).
    """
    largest = largest_tolerance(diagonal, magnitude, settings, deflection=deflection)
    reach = largest + (largest_clearance(settings) or 0.0) + margin
    lower, upper = hulls.lower, hulls.upper
    n = len(lower)
    first = np.arange(n, dtype=np.int64)  # each part's set's first copy (itself when alone)
    for members in copies:
        first[members] = members[0]
    stands = np.flatnonzero(first == np.arange(n))
    if not copies:
        pairs = candidate_pairs(lower, upper, margin=reach)
    else:  # a set stands in with the box around its copies' boxes, then each copy's own decides
        low, high = lower.copy(), upper.copy()
        np.minimum.at(low, first, lower)
        np.maximum.at(high, first, upper)
        sets = stands[candidate_pairs(low[stands], high[stands], margin=reach)]
        order = np.argsort(first, kind="stable")  # the copies of each set together
        starts = np.searchsorted(first[order], np.arange(n + 1))
        lo, hi = lower - 0.5 * reach, upper + 0.5 * reach  # candidate_pairs' own comparison
        box, _ = group_pairs(lo[order], hi[order], starts[:-1], np.diff(starts), sets, 0.0)
        i, j = order[box[:, 0]], order[box[:, 1]]
        pairs = np.stack([np.minimum(i, j), np.maximum(i, j)], axis=1).astype(np.int64)
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]  # as candidate_pairs sorts
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
    classes: PairClasses,
    settings: Settings,
    *,
    executor: Executor | None = None,
    geometry: dict | None = None,
    cache: DecompositionCache | None = None,
    known: dict[int, list[np.ndarray]] | None = None,
) -> tuple[list[ConvexPack], np.ndarray]:
    """Convex pieces of each geometry of the pair ``classes`` (``verify.classes``): CoACD's
    where the cost model says they pay (``decompose.coacd_budgets``, counting the verify work of
    one pair per class), the hull elsewhere. CoACD runs on ``executor`` (default:
    ``settings.jobs`` local processes); pieces are kept in ``cache``, the run's decompositions
    (``decompose.decompose_shapes``). A geometry of a part in ``known`` (body index -> world
    pieces: the sweep's, ``sweep.mechanism_pieces``) keeps those.

    Returns
    -------
    packs : list of ConvexPack
        The pieces of each of ``classes.shapes``, in the geometry's own frame (its local
        vertices'), packed once (an empty pack for a geometry no class needs).
    count : (n,) int64
        Pieces of each part's geometry; 0 for parts in no class.
    """
    geometry = local_geometries(bodies) if geometry is None else geometry
    reps = classes.pairs[classes.first]
    needed = np.unique(reps)
    chosen = [bodies[i] for i in needed]
    rank = np.full(len(bodies), -1, dtype=np.int64)
    rank[needed] = np.arange(len(needed))
    forced = os.environ.get(BUDGET_VARIABLE)
    budgets = coacd_budgets(
        chosen, rank[reps], geometry=geometry, forced=float(forced) if forced else None
    )
    known = known or {}
    shape_of = {g.digest: s for s, g in enumerate(classes.shapes)}
    local_known: dict[int, list[np.ndarray]] = {}
    for i in sorted(known):  # the sweep's pieces, back in their geometry's frame
        g = geometry[id(bodies[i].mesh)]
        s = shape_of.get(g.digest)
        if s is not None and s not in local_known:
            local_known[s] = _local_pieces(known[i], bodies[i].transform, g.corner)
    fresh: dict[int, Body] = {}  # one body per geometry to decompose
    for i in needed:
        s = shape_of[geometry[id(bodies[i].mesh)].digest]
        if s not in local_known:
            fresh.setdefault(s, bodies[i])
    with Progress("decomposing", len(fresh)) as bar:
        pieces_of, _ = decompose_shapes(
            list(fresh.values()),
            threshold=settings.threshold,
            cache=cache,
            jobs=settings.jobs,
            progress=bar,
            time_limit=budgets,
            executor=executor,
            geometry=geometry,
        )
    # Pieces may carry extra interior points (triangle cover); a support scan over a superset of
    # the hull's vertices is still exact, so Qhull need not run again.
    packs = [pack_convex([np.zeros(3)], is_hull=True)] * len(classes.shapes)
    for s, piece_list in local_known.items():
        packs[s] = pack_convex(piece_list, is_hull=True)
    for s in fresh:
        packs[s] = pack_convex(pieces_of[classes.shapes[s].digest], is_hull=True)
    count = np.zeros(len(bodies), dtype=np.int64)
    used = np.unique(classes.pairs)
    pieces_per_shape = np.array([len(p.starts) - 1 for p in packs], dtype=np.int64)
    if len(used):
        count[used] = pieces_per_shape[classes.body_shape[used]]
    return packs, count


def _local_pieces(pieces: list[np.ndarray], transform: np.ndarray, corner: np.ndarray) -> list:
    """World pieces of a part moved back to its geometry's frame (its local vertices')."""
    transform = np.asarray(transform, dtype=np.float64)
    if np.array_equal(transform, np.eye(4)):
        return [p - corner for p in pieces]
    inverse = np.linalg.inv(transform[:3, :3])
    return [(p - transform[:3, 3]) @ inverse.T - corner for p in pieces]


def surfaces_near(
    packs: Sequence[ConvexPack],
    classes: PairClasses,
    clearance,
    margin: np.ndarray | None = None,
) -> np.ndarray:
    """Which ``classes`` have a piece pair within their reach (tolerance + clearance + margin,
    or undecided), ``(c,)`` bool, each in its own frame: the pieces of its two geometries placed
    as the verify stage places their meshes (``PairClasses.placed``), so what the pieces prove
    holds for the very triangles verified. A class without one has surfaces beyond its reach.
    ``margin`` ``(c,)`` is what the B-rep adds to a class of STEP solids' reach
    (``verify.brep.reach_margin``); default none.
    """
    c = len(classes)
    if c == 0:
        return np.zeros(0, dtype=bool)
    which = np.empty(2 * c, dtype=np.int64)
    transforms = np.broadcast_to(np.eye(4), (2 * c, 4, 4)).copy()
    for k, placed in enumerate(classes.placed):
        for side, p in enumerate(placed):
            which[2 * k + side] = p.shape
            transforms[2 * k + side, :3, :3] = p.linear
            transforms[2 * k + side, :3, 3] = p.shift
    pieces = place_packs(packs, which, transforms)
    count = np.array([len(packs[s].starts) - 1 for s in which], dtype=np.int64)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    reach = classes.tolerance + (clearance or 0.0)
    if margin is not None:
        reach = reach + margin
    groups = np.arange(2 * c, dtype=np.int64).reshape(c, 2)
    piece_pairs, row = group_pairs(pieces.lower, pieces.upper, first, count, groups, reach)
    query = query_pairs(
        pieces, piece_pairs, tolerance=classes.tolerance[row], depth=False, max_distance=reach[row]
    )
    hit = may_come_within(query, reach[row])
    out = np.zeros(c, dtype=bool)
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
    if not approvals:  # nothing to approve: the findings as they are
        return [
            dataclasses.replace(f, approval_reason=None) if f.is_approved else f for f in findings
        ]
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


def _world_hulls(bodies: Sequence[Body], geometry: dict) -> ConvexPack:
    """The convex hull of each body, world coordinates, packed: its support points
    (``geometry.support_points``) found once per distinct geometry and moved to each body that
    has it (``geometry.place_packs``).

    Geometry is compared up to translation (``load.local_geometry``), so instances of one
    mesh and copies of one part at other places share a hull.
    """
    index: dict[str, int] = {}
    local: list[np.ndarray] = []
    which = np.empty(len(bodies), dtype=np.int64)
    by_mesh: dict[int, int] = {}
    for k, body in enumerate(bodies):
        g = by_mesh.get(id(body.mesh))
        if g is None:
            points, _, _, digest = geometry[id(body.mesh)]
            if digest not in index:
                index[digest] = len(local)
                local.append(support_points(points))
            g = by_mesh[id(body.mesh)] = index[digest]
        which[k] = g
    packs = [pack_convex([hull], is_hull=True) for hull in local]
    return place_packs(packs, which, *_placements(bodies, geometry))


def _placements(bodies: Sequence[Body], geometry: dict) -> tuple[np.ndarray, np.ndarray]:
    """Each body's transform ``(n, 4, 4)`` and its local geometry's corner ``(n, 3)``: where
    ``place_packs`` puts what was built once per geometry."""
    transforms = np.array([b.transform for b in bodies], dtype=np.float64).reshape(-1, 4, 4)
    corners = np.array([geometry[id(b.mesh)].corner for b in bodies]).reshape(-1, 3)
    return transforms, corners
