"""Body -> convex pieces that cover every triangle (CoACD; a convex body is its own single piece).

The pipeline clears a part pair when every piece of one part stays beyond reach of every piece of
the other. That is sound only if the pieces cover the part's surface, so each triangle of the mesh
lies inside at least one piece (all three vertices inside the same piece). CoACD's pieces only
approximate the mesh (merging, hull simplification and remeshing shrink them), so
``cover_triangles`` repairs them: every triangle not inside a piece has its vertices added to the
piece nearest its centroid.

Work is done once per distinct geometry: meshes are hashed in their own frame after moving their
lowest corner to the origin, so instances of one mesh (a GLB node placed many times) and the same
STL part at several positions share an entry; copies that differ only by float32 rounding reuse one
decomposition (then re-covered against their own triangles). Misses are decomposed as ``execute``
tasks (local worker processes with one OpenMP thread each, or a Dask cluster), and stored in the
cache by this process alone.

CoACD runs only where its pieces pay (``coacd_budgets``, the ``CostModel``): on a closed part
whose hull-near pairs would cost the exact stage more than CoACD is expected to take, and for no
longer than that saving. Elsewhere the part's convex hull stands in, as it does for a mesh CoACD
does not finish in time. Which pairs the pieces clear changes only how much work the exact stage
does, never a verdict, so none of this reaches a report.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .cache import DecompositionCache, decomposition_key
from .execute import Executor, LocalPool, Task, default_jobs
from .geometry import support_points
from .load import Body, is_closed, local_geometries
from .progress import Progress
from .settings import DEFAULT_THRESHOLD

# CoACD settings chosen with bench/coacd_settings.py (figures: docs/internals/benchmarks.md).
# The verify stage is exact, so the pieces only have to be a good filter: these are about fifty
# times faster than CoACD's defaults and filter a little worse, well ahead of the bare hull.
DEFAULT_OPTIONS = {
    "resolution": 300,  # surface samples for the concavity metric (default 2000)
    "mcts_nodes": 5,  # MCTS children per node (default 20)
    "mcts_iterations": 20,  # MCTS iterations (default 150)
    "mcts_max_depth": 1,  # MCTS search depth (default 3)
    # "auto" here means meshcheck's choice: "off" for closed, consistently wound meshes, "on" for
    # the rest. CoACD's own "auto" remeshed CAD plates with many holes (a voxel remesh that made
    # the pieces bulge 0.9 mm out of a 160 mm plate) and costs 1-4x the time.
    "preprocess_mode": "auto",
    "preprocess_resolution": 50,  # voxel grid of the remesh, only for open or non-manifold input
    "max_ch_vertex": 256,
    "merge": True,
    "seed": 0,  # CoACD is randomised: a fixed seed makes runs repeatable
}

# CoACD's time is erratic (bench/coacd_settings.py --slow shows a small settings change taking a
# gear a hundred times longer: bad early cuts split it into hundreds of pieces). Past its limit
# the worker is killed and the part's hull stands in for its pieces: the check stays exact, only
# slower for that part. The check gives each part the limit the cost model derives
# (``coacd_budgets``); this one is for callers of ``decompose_bodies`` that give none.
DEFAULT_TIME_LIMIT = 20.0

# A vertex counts as inside a piece when it is at most this fraction of the mesh's bounding-box
# diagonal outside one of the piece's face planes: room for qhull's rounding (~1e-15 relative),
# far below the touching tolerance (1e-5 of the assembly's diagonal).
COVER_TOLERANCE = 1e-9
# Copies of a mesh whose frame-local vertices agree to this fraction of its diagonal (float32
# rounding of STL coordinates at other positions) reuse one decomposition, re-covered.
NEAR_COPY_TOLERANCE = 1e-4


def is_convex(mesh) -> bool:
    """True when a closed mesh fills its convex hull (volumes equal within 1e-6)."""
    if not is_closed(mesh):
        return False
    try:
        hull = mesh.convex_hull
    except Exception:  # qhull fails on flat or degenerate input
        return False
    return bool(abs(hull.volume - abs(mesh.volume)) <= 1e-6 * hull.volume)


def coacd_options(threshold: float = DEFAULT_THRESHOLD, **overrides) -> dict:
    """Every CoACD option meshcheck passes, defaults filled in, keys sorted."""
    options = {**DEFAULT_OPTIONS, "threshold": float(threshold), **overrides}
    return dict(sorted(options.items()))


def run_coacd(mesh, **options) -> list[np.ndarray]:
    """Raw CoACD pieces of a mesh, frame-local (no cover fix-up).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Geometry in its own frame.
    **options
        Keyword options of ``coacd.run_coacd``; ``preprocess_mode="auto"`` (the default) skips
        CoACD's remesh for closed, consistently wound meshes and forces it for the rest.

    Returns
    -------
    pieces : list of (n_i, 3) float64
        Vertices of each convex piece; empty when CoACD fails on the input.
    """
    import coacd

    coacd.set_log_level("error")  # CoACD logs to stdout, which carries the report
    if options.get("preprocess_mode", "auto") == "auto":
        is_closed = mesh.is_watertight and mesh.is_winding_consistent
        options = {**options, "preprocess_mode": "off" if is_closed else "on"}
    try:
        parts = coacd.run_coacd(
            coacd.Mesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int32)),
            **options,
        )
    except Exception:  # CoACD rejects some degenerate inputs; the caller falls back to the hull
        return []
    return [np.asarray(v, dtype=np.float64).reshape(-1, 3) for v, _ in parts if len(v)]


def cover_triangles(
    vertices: np.ndarray,
    faces: np.ndarray,
    pieces: Sequence[np.ndarray],
    *,
    tolerance: float | None = None,
) -> list[np.ndarray]:
    """Grow convex pieces until every triangle lies inside one of them.

    A triangle is inside a piece when its three vertices are inside the piece's convex hull. Each
    triangle that is not gets its vertices added to the piece whose hull is nearest its centroid
    (smallest largest plane excess), and that piece is replaced by the hull of the union.

    Parameters
    ----------
    vertices : (n, 3) float64
        Mesh vertices, any frame.
    faces : (m, 3) int
        Triangles as vertex indices.
    pieces : sequence of (n_i, 3) float64
        Convex pieces (their convex hulls are the pieces), same frame.
    tolerance : float, optional
        How far outside a hull plane a vertex may be and still count as inside, model units.
        Default: ``COVER_TOLERANCE`` times the mesh's bounding-box diagonal.

    Returns
    -------
    pieces : list of (n_i, 3) float64
        The pieces, grown where needed (hull vertices, in qhull's order); one piece holding every
        vertex when ``pieces`` is empty. Same length as ``pieces`` otherwise.

    Examples
    --------
    >>> import trimesh
    >>> box = trimesh.creation.box()
    >>> grown = cover_triangles(box.vertices, box.faces, [box.vertices[:4]])
    >>> len(grown), len(grown[0])
    (1, 8)
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    pieces = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in pieces]
    if not pieces:
        return [_hull_vertices(vertices)]
    if tolerance is None:
        span = np.ptp(vertices, axis=0) if len(vertices) else np.zeros(3)
        tolerance = COVER_TOLERANCE * max(float(np.linalg.norm(span)), 1e-300)
    if not len(faces):
        return pieces

    planes = [_hull_planes(p) for p in pieces]
    for attempt in range(4):
        missing = _uncovered(vertices, faces, planes, tolerance)
        if not len(missing):
            break
        centroids = vertices[faces[missing]].mean(axis=1)
        target = np.argmin(_excess(centroids, planes), axis=1)
        for k in np.unique(target):
            extra = np.concatenate([pieces[k], vertices[np.unique(faces[missing[target == k]])]])
            if attempt < 3:
                pieces[k] = _hull_vertices(extra)
                planes[k] = _hull_planes(pieces[k])
            else:
                # qhull dropped a point it judged inside within its own precision: keep the raw
                # vertices, the piece's hull then contains the triangle by definition.
                pieces[k] = extra
    return pieces


def covers(vertices: np.ndarray, faces: np.ndarray, pieces: Sequence[np.ndarray]) -> bool:
    """True when every triangle lies inside one of the convex ``pieces`` (``cover_triangles``'
    condition, with its tolerance): the check a cached decomposition must pass to be used."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not len(faces):
        return True
    if not pieces:
        return False
    span = np.ptp(vertices, axis=0)
    tolerance = COVER_TOLERANCE * max(float(np.linalg.norm(span)), 1e-300)
    planes = [_hull_planes(np.asarray(p, dtype=np.float64).reshape(-1, 3)) for p in pieces]
    return not len(_uncovered(vertices, faces, planes, tolerance))


def _uncovered(vertices, faces, planes, tolerance) -> np.ndarray:
    """Indices of the triangles no piece holds all three vertices of."""
    inside = _excess(vertices, planes) <= tolerance
    covered = (inside[faces[:, 0]] & inside[faces[:, 1]] & inside[faces[:, 2]]).any(axis=1)
    return np.flatnonzero(~covered)


def _hull_vertices(points: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of ``points`` (all points when the hull is flat)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return np.ascontiguousarray(points[ConvexHull(points).vertices])
    except (QhullError, ValueError):
        return np.ascontiguousarray(points)


def _hull_planes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit outward normals (h, 3) and offsets (h,) of the hull of ``points``: n.x <= d inside.

    A flat or degenerate piece gets one impossible plane, so nothing counts as inside it.
    """
    from scipy.spatial import ConvexHull, QhullError

    try:
        eq = ConvexHull(points).equations
    except (QhullError, ValueError):
        return np.zeros((1, 3)), np.array([-np.inf])
    return np.ascontiguousarray(eq[:, :3]), -eq[:, 3]


def _excess(points: np.ndarray, planes: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Largest plane excess of each point over each piece, (n, p) float64; <= 0 means inside."""
    normals = np.concatenate([n for n, _ in planes])
    offsets = np.concatenate([d for _, d in planes])
    starts = np.cumsum([0] + [len(d) for _, d in planes[:-1]])
    out = np.empty((len(points), len(planes)))
    chunk = max(1, 4_000_000 // max(len(offsets), 1))
    for a in range(0, len(points), chunk):
        d = points[a : a + chunk] @ normals.T - offsets
        out[a : a + chunk] = np.maximum.reduceat(d, starts, axis=1)
    return out


def decompose_mesh(vertices: np.ndarray, faces: np.ndarray, options: dict) -> list[np.ndarray]:
    """Convex pieces covering every triangle of one mesh, in the mesh's frame.

    Parameters
    ----------
    vertices : (n, 3) float64
        Mesh vertices.
    faces : (m, 3) int64
        Triangles.
    options : dict
        CoACD options, from ``coacd_options``.

    Returns
    -------
    pieces : list of (n_i, 3) float64
        The hull alone for a convex mesh; CoACD's pieces grown by ``cover_triangles`` otherwise.
    """
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if is_convex(mesh):
        return [_hull_vertices(np.asarray(vertices, dtype=np.float64))]
    return cover_triangles(vertices, faces, run_coacd(mesh, **options))


def decompose_task(store: dict, vertices, faces, options) -> list[np.ndarray]:
    """``decompose_mesh`` as an ``execute`` task (the store is not used)."""
    return decompose_mesh(vertices, faces, options)


# ---------------------------------------------------------------------------------------------
# Where decomposing pays: the cost model


@dataclass(frozen=True)
class CostModel:
    """Expected seconds of CoACD on a mesh and of the exact verify stage on a pair.

    The pieces are only a filter in front of the exact stage: a hull-near pair whose pieces stay
    apart skips the triangle search (``verify.pair._near_pairs``) and keeps only the buried-shell
    test, which runs either way. A part's pieces can therefore save at most
    ``filter_share * sum(verify_seconds(pair))`` over its hull-near pairs; CoACD runs on it only
    when that exceeds ``coacd_seconds(triangles)``, and for no longer than that saving.

    Attributes
    ----------
    coacd_base, coacd_per_triangle : float
        ``coacd_seconds(n) = coacd_base + coacd_per_triangle * n``, one core, meshcheck's
        CoACD settings.
    verify_base, verify_per_triangle : float
        ``verify_seconds(n_a, n_b) = verify_base + verify_per_triangle * (n_a + n_b)``: the
        triangle search of one hull-near pair that the pieces would clear.
    filter_share : float
        Share of a part's hull-near pairs its pieces clear: the upper end measured, so the model
        leans towards decomposing.
    """

    coacd_base: float
    coacd_per_triangle: float
    verify_base: float
    verify_per_triangle: float
    filter_share: float

    def coacd_seconds(self, triangles: int) -> float:
        """Expected seconds of CoACD on a closed mesh of ``triangles`` triangles."""
        return self.coacd_base + self.coacd_per_triangle * triangles

    def verify_seconds(self, triangles_a: int, triangles_b: int) -> float:
        """Expected seconds of the triangle search of a pair the pieces would clear."""
        return self.verify_base + self.verify_per_triangle * (triangles_a + triangles_b)


#: Calibrated with ``python bench/cost_model.py`` (docs/internals/benchmarks.md). CoACD's time per
#: triangle is erratic (3e-5 s on plates with holes to 2e-3 s on a pocketed housing): the
#: median part's, plus a worker's start. Verify: the least-squares line through the five parts'
#: savings. Filter share: the largest measured (0.39), so the model leans towards decomposing.
COST_MODEL = CostModel(
    coacd_base=0.5,
    coacd_per_triangle=3.0e-4,
    verify_base=5.0e-4,
    verify_per_triangle=1.2e-6,
    filter_share=0.4,
)


def coacd_budgets(
    bodies: Sequence[Body],
    pairs: np.ndarray,
    *,
    geometry: dict | None = None,
    model: CostModel = COST_MODEL,
    forced: float | None = None,
) -> dict[str, float]:
    """Seconds CoACD may spend on each distinct geometry; 0 where its pieces cannot pay.

    A function of the inputs only (triangle counts, closedness, the hull-near ``pairs``), so the
    choice is the same on every run. (Pieces a cache already holds are used whatever it says:
    which pairs the pieces clear changes the exact stage's work, never a verdict.)

    Parameters
    ----------
    bodies : sequence of Body
    pairs : (k, 2) int64
        The hull-near part pairs, indices into ``bodies``.
    geometry : dict, optional
        ``load.local_geometries(bodies)``, when the caller has it.
    model : CostModel
    forced : float, optional
        For tests and benchmarks: every geometry gets this budget, whatever it saves, open or
        closed (the trust tests of the decomposition cache use open meshes).

    Returns
    -------
    budgets : dict
        Digest of each distinct frame-local geometry (``load.local_geometry``) -> seconds: the
        verify work its pieces could save when that exceeds CoACD's expected time, else 0.
        Open meshes always get 0 (CoACD remeshes them into a different surface, slowly).
    """
    geometry = local_geometries(bodies) if geometry is None else geometry
    digests = [geometry[id(b.mesh)].digest for b in bodies]
    triangles = np.array([len(b.mesh.faces) for b in bodies], dtype=np.int64)
    saving = dict.fromkeys(digests, 0.0)
    for i, j in np.asarray(pairs, dtype=np.int64).reshape(-1, 2):
        seconds = model.filter_share * model.verify_seconds(triangles[i], triangles[j])
        saving[digests[i]] += seconds
        saving[digests[j]] += seconds
    budgets = {}
    for body, digest, n in zip(bodies, digests, triangles, strict=True):
        if digest not in budgets:
            pays = body.is_closed and saving[digest] > model.coacd_seconds(int(n))
            budgets[digest] = saving[digest] if pays else 0.0
            if forced is not None:
                budgets[digest] = float(forced)
    return budgets


# ---------------------------------------------------------------------------------------------
# Decomposing bodies


@dataclass(frozen=True)
class Shape:
    """One distinct frame-local geometry among the bodies (``load.local_geometry``).

    Attributes
    ----------
    digest : str
        Hex SHA-256 of ``local`` and ``faces``.
    local : (n, 3) float64
        Vertices with their lowest corner at the origin.
    faces : (m, 3) int64
    name : str
        The first body with this geometry, for progress lines.
    """

    digest: str
    local: np.ndarray
    faces: np.ndarray
    name: str

    @property
    def topology(self) -> tuple:
        """Equal for copies that differ only by rounding of their vertices."""
        return (self.local.shape, hashlib.sha256(self.faces.tobytes()).hexdigest())


@dataclass(frozen=True)
class Placed:
    """Where a body's geometry sits: world = (local + corner) placed by ``transform``."""

    digest: str
    corner: np.ndarray  # (3,) float64
    transform: np.ndarray  # (4, 4) float64


def decompose_bodies(
    bodies: Sequence[Body],
    *,
    threshold: float = DEFAULT_THRESHOLD,
    cache: DecompositionCache | None = None,
    cache_dir: str | None = None,
    jobs: int | None = None,
    options: dict | None = None,
    progress: Progress | None = None,
    time_limit: float | dict[str, float] | None = DEFAULT_TIME_LIMIT,
    executor: Executor | None = None,
    geometry: dict | None = None,
) -> list[list[np.ndarray]]:
    """Convex pieces of each body in world coordinates, covering every triangle of the body.

    Parameters
    ----------
    bodies : sequence of Body
        Bodies to decompose.
    threshold : float
        CoACD concavity threshold.
    cache : cache.DecompositionCache, optional
        The run's decompositions (``cache.open_caches``): entries signed with the run's key are
        used as they are, others only when they cover their mesh; new ones are stored, signed.
        None (and no ``cache_dir``) neither reads nor writes a cache.
    cache_dir : str, optional
        Instead of ``cache``: a decomposition cache in this directory, without a key (every entry
        is checked against its mesh before use).
    jobs : int, optional
        Worker processes; default all cores, never more than meshes to decompose. With a time
        limit, CoACD always runs in workers (one for a single mesh), so an overrun can be killed
        and the main process never loads CoACD.
    options : dict, optional
        Other CoACD options, overriding ``DEFAULT_OPTIONS``.
    progress : progress.Progress, optional
        Told the distinct meshes done, what CoACD works on, and (``note``) time-outs.
    time_limit : float or dict, optional
        Seconds CoACD may spend on a mesh: one for all, or per digest of frame-local geometry
        (``coacd_budgets``), 0 meaning "not worth it": the hull stands in, not cached. A mesh
        that overruns gets its convex hull (a valid, coarser cover), cached so. None: no limit,
        and a single mesh is decomposed in this process.
    executor : execute.Executor, optional
        Where CoACD runs (a run's pool or Dask cluster); default ``jobs`` processes started for
        this call. A one-process ``Executor`` with a time limit is replaced by one worker.
    geometry : dict, optional
        ``load.local_geometries`` of the bodies, when the caller has it already.

    Returns
    -------
    pieces : list of list of (n_i, 3) float64
        For each body, its convex pieces' vertices, world coordinates, model units.
    """
    pieces_of, placed = decompose_shapes(
        bodies,
        threshold=threshold,
        cache=cache,
        cache_dir=cache_dir,
        jobs=jobs,
        options=options,
        progress=progress,
        time_limit=time_limit,
        executor=executor,
        geometry=geometry,
    )
    return [_world_pieces(pieces_of[p.digest], p) for p in placed]


def decompose_shapes(
    bodies: Sequence[Body],
    *,
    threshold: float = DEFAULT_THRESHOLD,
    cache: DecompositionCache | None = None,
    cache_dir: str | None = None,
    jobs: int | None = None,
    options: dict | None = None,
    progress: Progress | None = None,
    time_limit: float | dict[str, float] | None = DEFAULT_TIME_LIMIT,
    executor: Executor | None = None,
    geometry: dict | None = None,
) -> tuple[dict[str, list[np.ndarray]], list[Placed]]:
    """``decompose_bodies`` before the pieces are placed: the frame-local pieces of each
    distinct geometry (by ``load.local_geometry`` digest), and each body's ``Placed`` (its
    pieces in the world are ``(piece + corner)`` under its transform). The arguments are
    ``decompose_bodies``'."""
    if cache is not None and cache_dir is not None:
        raise TypeError("give cache or cache_dir, not both")
    if cache_dir is not None:
        cache = DecompositionCache(cache_dir)
    settings = coacd_options(threshold, **(options or {}))
    shapes, placed = _distinct_shapes(
        bodies, local_geometries(bodies) if geometry is None else geometry
    )
    keys, pieces_of = _cached_pieces(shapes, cache, settings)
    misses = [d for d in shapes if d not in pieces_of]
    unpaid = {d for d, limit in _time_limits(time_limit, misses).items() if limit == 0.0}
    leaders = _near_copies(shapes, pieces_of, misses, unpaid)
    limits = _time_limits(time_limit, [d for d in misses if d not in leaders])
    pieces_of.update(
        _decompose_misses(shapes, limits, settings, jobs, executor, progress, len(pieces_of))
    )
    for digest, leader in leaders.items():
        shape = shapes[digest]
        pieces_of[digest] = cover_triangles(
            shape.local, shape.faces, [p.copy() for p in pieces_of[leader]]
        )
    _show_done(progress, len(pieces_of))
    if cache is not None:
        _store_decomposed(cache, keys, pieces_of, misses, leaders, limits)
    return pieces_of, placed


def _decompose_misses(shapes, limits, settings, jobs, executor, progress, done) -> dict:
    """Pieces of the shapes to decompose (the keys of ``limits``, ``done`` others done): the hull
    where it stands in (``_hull_stands_in``), CoACD's covering pieces elsewhere."""
    _show_done(progress, done)
    stands_in = {d: _hull_stands_in(shapes[d], limit) for d, limit in limits.items()}
    out = {d: [support_points(shapes[d].local)] for d in limits if stands_in[d]}
    _show_done(progress, done + len(out))
    concave = [d for d in limits if not stands_in[d]]
    out.update(
        _coacd_or_hull(shapes, concave, limits, settings, jobs, executor, progress, done + len(out))
    )
    return out


def _store_decomposed(
    cache: DecompositionCache,
    keys: dict,
    pieces_of: dict,
    misses: list,
    leaders: dict,
    limits: dict,
) -> None:
    """Cache the misses' pieces. A hull that stood in because CoACD would not pay is not a
    decomposition: not cached, so a run where the part has more neighbours decomposes it."""
    unpaid = {d for d, limit in limits.items() if limit == 0.0}
    for digest in misses:
        if leaders.get(digest, digest) not in unpaid:
            cache.put(keys[digest], pieces_of[digest])


def _show_done(progress: Progress | None, done: int) -> None:
    """Tell ``progress`` (when there is one) how many distinct meshes are done."""
    if progress is not None:
        progress.update(done)


def _distinct_shapes(
    bodies: Sequence[Body], geometry: dict
) -> tuple[dict[str, Shape], list[Placed]]:
    """The distinct geometries in order of first appearance, and each body's placement."""
    shapes: dict[str, Shape] = {}
    placed = []
    for body in bodies:
        local, faces, corner, digest = geometry[id(body.mesh)]
        if digest not in shapes:
            shapes[digest] = Shape(digest, local, faces, body.name)
        transform = np.asarray(body.transform, dtype=np.float64)
        placed.append(Placed(digest, corner, transform))
    return shapes, placed


def _cached_pieces(
    shapes: dict[str, Shape], cache: DecompositionCache | None, settings: dict
) -> tuple[dict, dict]:
    """Cache keys of the shapes, and the pieces of those the cache holds and may be trusted.

    The cache is input from outside: an entry is used only when its pieces cover every triangle
    of the mesh, which is all the filter's exactness rests on, or when it is signed with the
    run's key (written by a run that held it, from covering pieces).
    """
    keys: dict[str, str] = {}
    pieces_of: dict[str, list[np.ndarray]] = {}
    if cache is None:
        return keys, pieces_of
    for digest, shape in shapes.items():
        keys[digest] = decomposition_key(digest, settings)
        hit = cache.lookup(keys[digest])
        if hit is not None and (hit[1] or covers(shape.local, shape.faces, hit[0])):
            pieces_of[digest] = hit[0]
    return keys, pieces_of


def _near_copies(
    shapes: dict[str, Shape], pieces_of: dict, misses: list[str], unpaid: set[str] = frozenset()
) -> dict[str, str]:
    """Misses that are copies (within ``NEAR_COPY_TOLERANCE``) of a cached shape or of an
    earlier miss: digest -> the digest whose pieces it reuses (re-covered). A miss CoACD would
    not run on (``unpaid``) follows no other such miss: both stand in with their own hulls,
    cheaper than re-covering one with the other's (and, not cached, paid again every run)."""
    by_topology: dict[tuple, list[str]] = {}
    for digest in pieces_of:
        by_topology.setdefault(shapes[digest].topology, []).append(digest)
    leaders: dict[str, str] = {}
    for digest in misses:
        shape = shapes[digest]
        span = float(np.linalg.norm(np.ptp(shape.local, axis=0))) if len(shape.local) else 0.0
        for leader in by_topology.get(shape.topology, []):
            if digest in unpaid and leader in unpaid:
                continue
            gap = np.max(np.abs(shapes[leader].local - shape.local), initial=0.0)
            if gap <= NEAR_COPY_TOLERANCE * span:
                leaders[digest] = leader
                break
        else:
            by_topology.setdefault(shape.topology, []).append(digest)
    return leaders


def _time_limits(time_limit, digests: list[str]) -> dict[str, float | None]:
    """Each digest's CoACD time limit, from one for all or one per digest (``time_limit``):
    0 for "not worth it", None for no limit."""
    if isinstance(time_limit, dict):
        return {d: float(time_limit.get(d, 0.0)) for d in digests}
    return dict.fromkeys(digests, time_limit)


def _hull_stands_in(shape: Shape, limit: float | None) -> bool:
    """Whether the shape's hull is its only piece: CoACD has no budget for it, or the mesh is
    convex (its own hull)."""
    import trimesh

    return limit == 0.0 or is_convex(trimesh.Trimesh(shape.local, shape.faces, process=False))


def _coacd_or_hull(shapes, concave, limits, settings, jobs, executor, progress, done) -> dict:
    """CoACD's covering pieces of each concave shape; the hull where it overran or crashed,
    said on ``progress`` as a note (how the run went belongs to no report)."""
    results = _map_coacd(
        [shapes[d] for d in concave],
        [limits[d] for d in concave],
        settings,
        jobs=jobs,
        executor=executor,
        progress=progress,
        done=done,
    )
    out = {}
    for digest, pieces in zip(concave, results, strict=True):
        if pieces is None:
            limit = limits[digest]
            why = f"took over {limit:.3g} s" if limit is not None else "crashed"
            if progress is not None:
                progress.note(
                    f"{shapes[digest].name}: convex decomposition {why}; its hull stands in "
                    "(the check stays exact, this part's pairs are verified on the real meshes)"
                )
            pieces = [_hull_vertices(shapes[digest].local)]
        out[digest] = pieces
    return out


def _world_pieces(pieces: list[np.ndarray], placed: Placed) -> list[np.ndarray]:
    """Frame-local pieces moved to the body's place in the world."""
    out = []
    is_moved = not np.array_equal(placed.transform, np.eye(4))
    for piece in pieces:
        p = piece + placed.corner
        if is_moved:
            p = p @ placed.transform[:3, :3].T + placed.transform[:3, 3]
        out.append(p)
    return out


def _map_coacd(
    shapes: list[Shape],
    limits: list[float | None],
    options: dict,
    *,
    jobs: int | None,
    executor: Executor | None,
    progress: Progress | None,
    done: int,
) -> list[list[np.ndarray] | None]:
    """CoACD on each shape; None for a shape that overran its limit or crashed its worker.

    Without any limit and with one job, shapes are decomposed in this process. Otherwise they
    run in worker processes (or on the given executor), largest mesh first.
    """
    if not shapes:
        return []
    tasks = [
        Task((s.local, s.faces, options), size=len(s.faces), time_limit=limit)
        for s, limit in zip(shapes, limits, strict=True)
    ]
    has_limit = any(limit is not None for limit in limits)
    own = None
    if executor is None or (not isinstance(executor, LocalPool) and not executor.is_distributed):
        workers = 1 if executor is not None else min(jobs or default_jobs(), len(tasks))
        if workers <= 1 and not has_limit:
            executor = Executor()
        else:
            executor = own = LocalPool(workers)
    if progress is not None:
        progress.detail = lambda: ", ".join(shapes[i].name for i in executor.running)
    try:
        return executor.map(
            "meshcheck.decompose:decompose_task",
            tasks,
            progress=None if progress is None else (lambda k: progress.update(done + k)),
        )
    finally:
        if progress is not None:
            progress.detail = None
        if own is not None:
            own.close()
