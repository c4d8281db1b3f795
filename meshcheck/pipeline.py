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

from . import verify
from .broadphase import candidate_pairs, group_pairs
from .cache import PairCache, pair_key, pair_secret
from .config import Approval, approval_reason
from .decompose import decompose_bodies
from .errors import MeshcheckWarning
from .execute import Executor, Task, executor_for
from .geometry import ConvexPack, Status, pack_convex, query_pairs
from .load import Body, Limits, load_bodies, local_geometries
from .progress import Progress
from .results import CheckResult, Finding, Location, Part, Verdict, finding_id
from .settings import (
    FLOAT32_ULPS,
    TOLERANCE_FRACTION,
    Settings,
    pair_tolerances,
    part_sizes,
)
from .units import DEFAULT_UNIT

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
            with Progress("loading", 0) as bar:
                limits = None
                if settings.max_triangles is not None:
                    limits = Limits(max_triangles=settings.max_triangles)
                bodies = load_bodies(
                    paths,
                    split=settings.split,
                    units=settings.units,
                    limits=limits,
                    cache_dir=settings.cache_dir,
                    step_deflection=settings.step_deflection,
                    progress=bar.update_total,
                    executor=executor,
                )
            result = check_bodies(bodies, settings, executor=executor)
    finally:
        # Re-issue outside the recorder, so callers' filters (and the CLI) see them as usual;
        # a message said twice (the same file's problem met by two stages) is said once.
        first: dict = {}
        for w in caught:
            first.setdefault((w.category, str(w.message)), w)
        caught = list(first.values())
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    messages = [str(w.message) for w in caught if issubclass(w.category, MeshcheckWarning)]
    return dataclasses.replace(result, warnings=[*result.warnings, *messages])


def check_bodies(
    bodies: Sequence[Body],
    settings: Settings | None = None,
    *,
    executor: Executor | None = None,
    **fields,
) -> CheckResult:
    """Run the check on bodies already loaded; see ``check``.

    ``settings`` defaults to ``Settings(**fields)`` (there ``cache_dir=None`` means no cache).
    ``executor`` is the run's (left open); default: one for ``settings.jobs`` and
    ``settings.scheduler``, closed at the end.
    """
    if settings is None:
        settings = Settings(**fields)
    names = [_names(b) for b in bodies]
    _check_patterns(settings, names)
    # The key cache entries are signed with, read once for the run (None: no cache).
    secret = None if settings.cache_dir is None else pair_secret()

    geometry = local_geometries(bodies)
    with Progress("comparing hulls", 0):
        hulls = pack_convex(_world_hulls(bodies, geometry), is_hull=True)
        diagonal, magnitude = part_sizes(hulls.lower, hulls.upper)
        deflection = max((b.deflection for b in bodies), default=0.0)
        pairs = select_pairs(hulls, settings, names, diagonal, magnitude, deflection)
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
            np.unique(pairs_near),
            settings,
            executor=executor,
            geometry=geometry,
            secret=secret,
        )
        near_surfaces = surfaces_near(pieces, owner, pairs_near, tol_near, reach_near)
        findings = verify_pairs(
            bodies, pairs_near, tol_near, near_surfaces, settings, executor=executor, secret=secret
        )
    findings = approve(
        findings, settings.approvals, dict(zip([b.name for b in bodies], names, strict=True))
    )
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


def decompose_parts(
    bodies: Sequence[Body],
    needed: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    geometry: dict | None = None,
    secret: bytes | None = None,
) -> tuple[ConvexPack, np.ndarray, np.ndarray]:
    """Convex pieces of the parts in ``needed`` (indices into ``bodies``), CoACD running on
    ``executor`` (default: ``settings.jobs`` local processes); cached entries are signed with
    ``secret`` (``decompose.decompose_bodies``).

    Returns
    -------
    pieces : ConvexPack
        The pieces of all needed parts, world coordinates, grouped by part.
    owner : (p,) int64
        The part index of each piece.
    count : (n,) int64
        Pieces per part; 0 for parts not needed.
    """
    with Progress("decomposing", len({id(bodies[i].mesh) for i in needed})) as bar:
        piece_lists = decompose_bodies(
            [bodies[i] for i in needed],
            threshold=settings.threshold,
            cache_dir=settings.cache_dir,
            jobs=settings.jobs,
            progress=bar.update,
            executor=executor,
            geometry=geometry,
            secret=secret,
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


#: Fewer pairs than this to verify are verified in this process: starting worker processes
#: (imports, loading the compiled kernels) costs more than the pairs take.
#: ``python bench/verify_parallel.py --size 800`` on a quiet 2-core machine: a fresh 2-process
#: pool took 1.63x the serial time at 100 pairs, 1.12x at 200, 0.87x at 400, 0.74x at 720 (on
#: the same machine shared with other jobs the crossover moved to ~1,000 pairs).
PARALLEL_MIN_PAIRS = 300
#: Pairs per task sent to a worker: enough to amortise a message, few enough to balance.
PAIRS_PER_TASK = 16


def verify_pairs(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    tolerance: np.ndarray,
    near_surfaces: np.ndarray,
    settings: Settings,
    *,
    executor: Executor | None = None,
    secret: bytes | None = None,
) -> list[Finding]:
    """Decide each pair on the real meshes; a finding for each pair that is not clear, sorted.

    With ``secret`` (the run's cache key) and a cache directory, verdicts cached from an earlier
    run (``cache.PairCache``: same meshes, placement, tolerance and clearance) are reused; the
    rest are verified, on ``executor``'s processes when there are at least
    ``PARALLEL_MIN_PAIRS`` of them, and then cached. The findings do not depend on where a
    verdict came from.
    """
    pairs = _oriented(bodies, np.asarray(pairs, dtype=np.int64).reshape(-1, 2))
    verdicts: list[verify.PairVerdict | None] = [None] * len(pairs)
    cache = None
    if settings.cache_dir is not None and secret is not None:
        cache = PairCache(settings.cache_dir, secret=secret)
    keys: list[str] = []
    if cache is not None:
        for k, ((i, j), tol, is_near) in enumerate(
            zip(pairs, tolerance, near_surfaces, strict=True)
        ):
            keys.append(
                pair_key(
                    (bodies[i].digest, bodies[i].transform),
                    (bodies[j].digest, bodies[j].transform),
                    tolerance=float(tol),
                    clearance=settings.clearance,
                    surfaces_apart=not is_near,
                )
            )
            hit = cache.get(keys[k])
            if hit is not None:
                verdicts[k] = _verdict(hit)
    todo = np.array([k for k, v in enumerate(verdicts) if v is None], dtype=np.int64)
    hits = len(pairs) - len(todo)
    with Progress("checking", len(pairs)) as bar:
        bar.update(hits)
        computed = _verify(
            bodies,
            pairs[todo],
            np.asarray(tolerance)[todo],
            np.asarray(near_surfaces)[todo],
            settings.clearance,
            executor,
            lambda done: bar.update(hits + done),
        )
    for k, verdict in zip(todo, computed, strict=True):
        verdicts[k] = verdict
        if cache is not None:
            cache.put(keys[k], _fields(verdict))
    if cache is not None and len(todo):
        cache.remove_stale_temporaries()

    findings = []
    for (i, j), tol, verdict in zip(pairs, tolerance, verdicts, strict=True):
        if verdict.status == Verdict.CLEAR:
            continue
        a, b = bodies[i], bodies[j]
        (name_a, digest_a), (name_b, digest_b) = sorted([(a.name, a.digest), (b.name, b.digest)])
        findings.append(
            Finding(
                a=name_a,
                b=name_b,
                status=verdict.status,
                distance=verdict.distance,
                depth=verdict.depth,
                volume=verdict.volume,
                location=verdict.location,
                id=finding_id(name_a, digest_a, name_b, digest_b),
                is_surface_only=verdict.is_surface_only,
                tolerance=float(tol),
            )
        )
    findings.sort(key=lambda f: (f.a, f.b))
    return findings


def _oriented(bodies: Sequence[Body], pairs: np.ndarray) -> np.ndarray:
    """``pairs`` with each pair's parts ordered by geometry and placement, not by where their
    files came in the arguments: a verdict, bit for bit, and its cache key do not depend on the
    order the files were given in."""
    if not len(pairs):
        return pairs
    used = np.unique(pairs)
    placed = sorted(used, key=lambda i: (bodies[i].digest, _placement_bytes(bodies[i])))
    rank = np.empty(int(used.max()) + 1, dtype=np.int64)
    rank[placed] = np.arange(len(placed))
    swap = rank[pairs[:, 0]] > rank[pairs[:, 1]]
    return np.where(swap[:, None], pairs[:, ::-1], pairs)


def _placement_bytes(body: Body) -> bytes:
    return np.ascontiguousarray(body.transform, dtype=np.float64).tobytes()


def verify_task(store: dict, items: list, clearance: float | None) -> list[verify.PairVerdict]:
    """Verify a chunk of pairs in a worker: ``items`` are ``(key_a, key_b, tolerance,
    surfaces_apart)``, the keys naming ``(vertices, faces)`` of world meshes in ``store``.

    The meshes are rebuilt once per process (kept in ``store``), bit for bit the arrays the main
    process holds, so each verdict is the one ``verify_pair`` gives there.
    """
    import trimesh

    memo = store.setdefault(("verify", "memo"), {})
    out = []
    for key_a, key_b, tol, apart in items:
        meshes = []
        for key in (key_a, key_b):
            mesh = store.get(("verify", "mesh", key))
            if mesh is None:
                vertices, faces = store[key]
                mesh = trimesh.Trimesh(vertices, faces, process=False, validate=False)
                store[("verify", "mesh", key)] = mesh
            meshes.append(mesh)
        out.append(
            verify.verify_pair(
                *meshes, tolerance=tol, clearance=clearance, surfaces_apart=apart, memo=memo
            )
        )
    return out


def _verify(bodies, pairs, tolerance, near_surfaces, clearance, executor, progress) -> list:
    """Verdicts of ``pairs`` in order: here, or as tasks of ``PAIRS_PER_TASK`` pairs."""
    # Workers already started (by loading or decomposition) cost nothing more to use.
    started = executor is not None and executor.is_started
    least = 2 * PAIRS_PER_TASK if started else PARALLEL_MIN_PAIRS
    parallel = executor is not None and (
        executor.is_distributed or (executor.jobs > 1 and len(pairs) >= least)
    )
    if not parallel:
        memo: dict = {}  # per-mesh data verify reuses across pairs; the bodies outlive the loop
        out = []
        for count, ((i, j), tol, is_near) in enumerate(
            zip(pairs, tolerance, near_surfaces, strict=True), start=1
        ):
            out.append(
                verify.verify_pair(
                    bodies[i].world,
                    bodies[j].world,
                    tolerance=float(tol),
                    clearance=clearance,
                    surfaces_apart=not is_near,
                    memo=memo,
                )
            )
            progress(count)
        return out

    # One shared value per distinct world mesh, named by the first body that has it.
    key_of: dict[int, int] = {}
    shared: dict = {}
    for i in np.unique(pairs):
        world = bodies[i].world
        if id(world) not in key_of:
            key_of[id(world)] = int(i)
            shared[int(i)] = (
                np.asarray(world.vertices, dtype=np.float64),
                np.asarray(world.faces, dtype=np.int64),
            )
    items = [
        (key_of[id(bodies[i].world)], key_of[id(bodies[j].world)], float(tol), not bool(near))
        for (i, j), tol, near in zip(pairs, tolerance, near_surfaces, strict=True)
    ]
    tasks = [
        Task(
            (items[a : a + PAIRS_PER_TASK], clearance),
            needs=tuple(sorted({k for it in items[a : a + PAIRS_PER_TASK] for k in it[:2]})),
        )
        for a in range(0, len(items), PAIRS_PER_TASK)
    ]
    results = executor.map(
        "meshcheck.pipeline:verify_task",
        tasks,
        shared=shared,
        progress=lambda done: progress(min(len(items), done * PAIRS_PER_TASK)),
    )
    out = []
    for task, result in zip(tasks, results, strict=True):
        if result is None:  # its worker died: verify here (a bug then shows its traceback)
            result = Executor().map("meshcheck.pipeline:verify_task", [task], shared=shared)[0]
        out.extend(result)
    progress(len(items))
    return out


def _verdict(fields: dict) -> verify.PairVerdict:
    location = fields["location"]
    if location is not None:
        location = Location(*location)
    return verify.PairVerdict(**(fields | {"location": location}))


def _fields(verdict: verify.PairVerdict) -> dict:
    where = verdict.location
    points = None if where is None else (where.centroid, where.lower, where.upper)
    return {f.name: getattr(verdict, f.name) for f in dataclasses.fields(verdict)} | {
        "location": points
    }


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
