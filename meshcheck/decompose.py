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
cache by this process alone. A mesh that CoACD has not
finished within ``DEFAULT_TIME_LIMIT`` seconds is represented by its convex hull instead.
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Callable, Sequence

import numpy as np

from .errors import MeshcheckWarning
from .execute import Executor, LocalPool, Task, default_jobs
from .load import Body, is_closed, local_geometries
from .settings import DEFAULT_THRESHOLD

# CoACD settings chosen with bench/coacd_settings.py (its figures are in README, "CoACD settings").
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
# gear a hundred times longer: bad early cuts split it into hundreds of pieces). Past this many
# seconds per mesh the worker is killed and the part's hull stands in for its pieces: the check
# stays exact, only slower for that part.
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


def decompose_bodies(
    bodies: Sequence[Body],
    *,
    threshold: float = DEFAULT_THRESHOLD,
    cache_dir: str | None = None,
    jobs: int | None = None,
    options: dict | None = None,
    progress: Callable[[int], None] | None = None,
    time_limit: float | None = DEFAULT_TIME_LIMIT,
    executor: Executor | None = None,
    geometry: dict | None = None,
    secret: bytes | None = None,
) -> list[list[np.ndarray]]:
    """Convex pieces of each body in world coordinates, covering every triangle of the body.

    Parameters
    ----------
    bodies : sequence of Body
        Bodies to decompose.
    threshold : float
        CoACD concavity threshold.
    cache_dir : str, optional
        Directory of the decomposition cache; None neither reads nor writes it.
    jobs : int, optional
        Worker processes; default all cores, never more than meshes to decompose. With a time
        limit, CoACD always runs in workers (one for a single mesh), so an overrun can be killed
        and the main process never loads CoACD.
    options : dict, optional
        Other CoACD options, overriding ``DEFAULT_OPTIONS``.
    progress : callable, optional
        Called with the number of meshes done each time some finish.
    time_limit : float, optional
        Seconds CoACD may spend on one mesh; a mesh that takes longer is represented by its
        convex hull (a valid, coarser cover) with a ``MeshcheckWarning``. None: no limit, and a
        single mesh is decomposed in this process.
    executor : execute.Executor, optional
        Where CoACD runs (a run's shared pool or Dask cluster); default a pool of ``jobs``
        processes started for this call. A one-process ``Executor`` with a time limit is replaced
        by one worker process, so an overrun can still be killed.
    geometry : dict, optional
        ``load.local_geometries`` of the bodies, when the caller has it already.
    secret : bytes, optional
        The run's cache key (``cache.pair_secret``): entries are signed with it, and entries
        signed with it are used without checking that they cover their mesh.

    Returns
    -------
    pieces : list of list of (n_i, 3) float64
        For each body, the vertices of its convex pieces, world coordinates, model units.
    """
    settings = coacd_options(threshold, **(options or {}))
    cache = None
    if cache_dir is not None:
        from .cache import DecompositionCache

        cache = DecompositionCache(cache_dir, secret=secret)

    # One entry per distinct frame-local geometry, in order of first appearance.
    if geometry is None:
        geometry = local_geometries(bodies)
    names: dict[str, str] = {}  # digest -> name of the first body with that geometry
    for body in bodies:
        names.setdefault(geometry[id(body.mesh)][3], body.name)
    distinct: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for body in bodies:
        local, faces, _, digest = geometry[id(body.mesh)]
        distinct.setdefault(digest, (local, faces))

    pieces_of: dict[str, list[np.ndarray]] = {}
    keys: dict[str, str] = {}
    if cache is not None:
        from .cache import cache_key

        for digest in distinct:
            keys[digest] = cache_key(digest, settings)
            hit = cache.lookup(keys[digest])
            # The cache is input from outside: an entry is used only when its pieces cover every
            # triangle of the mesh, which is all the filter's exactness rests on, or when it is
            # signed with the run's key (written by a run that held it, from covering pieces).
            if hit is not None and (hit[1] or covers(*distinct[digest], hit[0])):
                pieces_of[digest] = hit[0]
    done = len(pieces_of)
    if progress is not None and done:
        progress(done)

    # Misses: copies differing only by float32 rounding share the first one's decomposition.
    # Cached entries and earlier misses lead; a miss that matches one reuses its pieces.
    misses = [d for d in distinct if d not in pieces_of]
    leaders: dict[str, str] = {}
    by_topology: dict[tuple, list[str]] = {}
    for digest, (local, faces) in distinct.items():
        topo = (local.shape, hashlib.sha256(faces.tobytes()).hexdigest())
        if digest in pieces_of:
            by_topology.setdefault(topo, []).append(digest)
    for digest in misses:
        local, faces = distinct[digest]
        topo = (local.shape, hashlib.sha256(faces.tobytes()).hexdigest())
        span = float(np.linalg.norm(np.ptp(local, axis=0))) if len(local) else 0.0
        for leader in by_topology.get(topo, []):
            if np.max(np.abs(distinct[leader][0] - local), initial=0.0) <= (
                NEAR_COPY_TOLERANCE * span
            ):
                leaders[digest] = leader
                break
        else:
            by_topology.setdefault(topo, []).append(digest)
    todo = [d for d in misses if d not in leaders]

    # Convex meshes are their own hull: decided here, so a pool starts only for CoACD work.
    import trimesh

    concave = []
    for digest in todo:
        local, faces = distinct[digest]
        if is_convex(trimesh.Trimesh(local, faces, process=False)):
            pieces_of[digest] = [_hull_vertices(local)]
        else:
            concave.append(digest)
    done += len(todo) - len(concave)
    if progress is not None and len(todo) > len(concave):
        progress(done)
    results = _decompose_concave(
        [distinct[d] for d in concave], settings, jobs, executor, progress, done, time_limit
    )
    for digest, pieces in zip(concave, results, strict=True):
        if pieces is None:  # overran the time limit or crashed: the hull covers every triangle
            local = distinct[digest][0]
            pieces = [_hull_vertices(local)]
            limit = f"took over {time_limit:g} s or " if time_limit is not None else ""
            warnings.warn(
                f"{names[digest]}: convex decomposition {limit}crashed; "
                "the part's convex hull stands in for its pieces (the check stays exact)",
                MeshcheckWarning,
                stacklevel=2,
            )
        pieces_of[digest] = pieces
    for digest, leader in leaders.items():
        local, faces = distinct[digest]
        pieces_of[digest] = cover_triangles(local, faces, [p.copy() for p in pieces_of[leader]])
    if progress is not None and leaders:
        progress(done + len(concave) + len(leaders))
    if cache is not None:
        for digest in misses:
            cache.put(keys[digest], pieces_of[digest])

    out = []
    for body in bodies:
        _, _, corner, digest = geometry[id(body.mesh)]
        transform = np.asarray(body.transform, dtype=np.float64)
        world = []
        for piece in pieces_of[digest]:
            p = piece + corner
            if not np.array_equal(transform, np.eye(4)):
                p = p @ transform[:3, :3].T + transform[:3, 3]
            world.append(p)
        out.append(world)
    return out


def _decompose_concave(
    meshes: list[tuple[np.ndarray, np.ndarray]],
    options: dict,
    jobs: int | None,
    executor: Executor | None,
    progress: Callable[[int], None] | None,
    done: int,
    time_limit: float | None,
) -> list[list[np.ndarray] | None]:
    """CoACD on each mesh; None for a mesh that overran ``time_limit`` or crashed its worker.

    Without a time limit and with one job, meshes are decomposed in this process. Otherwise they
    run in worker processes (or on the given executor), largest mesh first.
    """
    if not meshes:
        return []
    tasks = [Task((v, f, options), size=len(f)) for v, f in meshes]

    def report(finished: int) -> None:
        if progress is not None:
            progress(done + finished)

    own = None
    if executor is None or (not isinstance(executor, LocalPool) and not executor.is_distributed):
        workers = min(jobs or default_jobs(), len(tasks))
        if executor is not None:
            workers = 1
        if workers <= 1 and time_limit is None:
            executor = Executor()
        else:
            executor = own = LocalPool(workers)
    try:
        return executor.map(
            "meshcheck.decompose:decompose_task", tasks, progress=report, time_limit=time_limit
        )
    finally:
        if own is not None:
            own.close()
