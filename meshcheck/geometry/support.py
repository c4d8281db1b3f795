"""Convex shapes for the support maps: many hulls packed in flat arrays for the batch kernel.

A convex shape is only ever asked one question: which of its points lies furthest along a
direction (its *support point*). Small hulls are scanned; hulls with more than
:data:`~meshcheck.geometry.constants.HILL_CLIMB_MIN_VERTICES` vertices walk their vertex
adjacency from the previous answer (hill climbing), which visits a handful of vertices. This
module builds what the support maps read (the vertices and that adjacency); the support maps
themselves are compiled, in ``src/support.hpp``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from . import _kernels
from .constants import HILL_CLIMB_MIN_VERTICES


class ConvexPack(NamedTuple):
    """Many convex shapes packed in flat arrays for :func:`meshcheck.geometry.query_pairs`.

    Attributes
    ----------
    points : (N, 3) float64
        Hull vertices of all shapes, concatenated, model units.
    starts : (m + 1,) int64
        Shape ``s`` owns ``points[starts[s]:starts[s + 1]]``.
    nbr_starts : (N + 1,) int64
        CSR row starts of the hull-vertex adjacency: the neighbours of vertex ``i`` are
        ``nbrs[nbr_starts[i]:nbr_starts[i + 1]]``. A shape whose first vertex has no neighbours
        (small or degenerate hulls) is scanned instead of walked.
    nbrs : (E,) int64
        Neighbour vertex indices, global into ``points``.
    lower : (m, 3) float64
        Axis-aligned bounding-box minimum of each shape.
    upper : (m, 3) float64
        Axis-aligned bounding-box maximum of each shape.
    """

    points: np.ndarray
    starts: np.ndarray
    nbr_starts: np.ndarray
    nbrs: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def _as_points(shape, index: int) -> np.ndarray:
    arr = np.asarray(shape, dtype=np.float64)
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ValueError(f"shape {index}: expected an (n, 3) array with n >= 1, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"shape {index}: coordinates must be finite")
    return arr


def _hull_vertices(arr: np.ndarray, is_hull: bool) -> tuple[np.ndarray, np.ndarray]:
    """Return one shape's support vertices and its local adjacency as (E, 2) directed edges."""
    no_edges = np.empty((0, 2), dtype=np.int64)
    n = arr.shape[0]
    if n <= 4 or (is_hull and n <= HILL_CLIMB_MIN_VERTICES):
        # A scan over a handful of points needs no hull, and duplicates are harmless to a scan
        # (dropping them with np.unique cost more than the scans they save).
        return arr, no_edges
    try:
        hull = ConvexHull(arr)
    except (QhullError, ValueError):
        # Flat, collinear or coincident points: no 3-D hull. The unique points are a valid
        # support set (a scan over them is exact).
        return np.unique(arr, axis=0), no_edges
    verts = arr[hull.vertices]
    nv = verts.shape[0]
    if nv <= HILL_CLIMB_MIN_VERTICES:
        return verts, no_edges
    local = np.full(n, -1, dtype=np.int64)
    local[hull.vertices] = np.arange(nv, dtype=np.int64)
    tri = local[hull.simplices]
    src = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2], tri[:, 1], tri[:, 2], tri[:, 0]])
    dst = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0], tri[:, 0], tri[:, 1], tri[:, 2]])
    key = np.unique(src * nv + dst)
    return verts, np.stack([key // nv, key % nv], axis=1)


def pack_convex(shapes: Sequence[np.ndarray], *, is_hull: bool = False) -> ConvexPack:
    """Pack the convex hulls of many point sets into flat arrays.

    Parameters
    ----------
    shapes : sequence of (n_i, 3) array-like of float
        Point sets, model units; each stands for its convex hull (a point, segment, flat polygon
        or solid). ``n_i >= 1``.
    is_hull : bool, keyword-only
        The caller promises the points are already hull vertices: hulls up to
        ``HILL_CLIMB_MIN_VERTICES`` points skip Qhull and are scanned; larger ones still go
        through Qhull once, to get the adjacency that hill climbing walks.

    Returns
    -------
    ConvexPack
        Hull vertices, adjacency (CSR) and bounding boxes of every shape, in input order.

    Raises
    ------
    ValueError
        A shape is not an (n, 3) array with n >= 1, or has non-finite coordinates.

    Examples
    --------
    >>> import numpy as np
    >>> pack = pack_convex([np.eye(3), np.eye(3) + 2.0])
    >>> pack.starts.tolist()
    [0, 3, 6]
    """
    verts_list: list[np.ndarray] = []
    edge_list: list[np.ndarray] = []
    starts = np.zeros(len(shapes) + 1, dtype=np.int64)
    total = 0
    for s, shape in enumerate(shapes):
        verts, edges = _hull_vertices(_as_points(shape, s), is_hull)
        verts_list.append(verts)
        edge_list.append(edges + total)
        total += verts.shape[0]
        starts[s + 1] = total
    if not verts_list:
        points = np.empty((0, 3), dtype=np.float64)
        edges = np.empty((0, 2), dtype=np.int64)
    else:
        points = np.ascontiguousarray(np.concatenate(verts_list), dtype=np.float64)
        edges = np.concatenate(edge_list)
    counts = np.bincount(edges[:, 0], minlength=total) if edges.size else np.zeros(total, np.int64)
    nbr_starts = np.zeros(total + 1, dtype=np.int64)
    np.cumsum(counts, out=nbr_starts[1:])
    nbrs = np.ascontiguousarray(edges[:, 1], dtype=np.int64)
    if verts_list:  # every shape has at least one point, so reduceat's segments are not empty
        lower = np.minimum.reduceat(points, starts[:-1], axis=0)
        upper = np.maximum.reduceat(points, starts[:-1], axis=0)
    else:
        lower = upper = np.empty((0, 3), dtype=np.float64)
    return ConvexPack(points, starts, nbr_starts, nbrs, lower, upper)


def triangle_pack(vertices: np.ndarray, faces: np.ndarray) -> ConvexPack:
    """Each triangle of a mesh as a convex shape of its own, packed without Qhull: three points
    are scanned (``pack_convex`` of the triangles, at array speed).

    Examples
    --------
    >>> import numpy as np
    >>> pack = triangle_pack(np.eye(3), np.array([[0, 1, 2], [2, 1, 0]]))
    >>> pack.starts.tolist(), pack.lower[0].tolist()
    ([0, 3, 6], [0.0, 0.0, 0.0])
    """
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    count = len(corners)
    return ConvexPack(
        np.ascontiguousarray(corners.reshape(-1, 3)),
        np.arange(0, 3 * count + 1, 3, dtype=np.int64),
        np.zeros(3 * count + 1, dtype=np.int64),
        np.empty(0, dtype=np.int64),
        corners.min(axis=1) if count else np.empty((0, 3)),
        corners.max(axis=1) if count else np.empty((0, 3)),
    )


def concat_packs(packs: Sequence[ConvexPack]) -> ConvexPack:
    """Join packs into one, shapes in order, offsetting every index.

    Parameters
    ----------
    packs : sequence of ConvexPack

    Returns
    -------
    ConvexPack
        Shape ``s`` of ``packs[p]`` becomes shape ``sum(len(packs[q].starts) - 1 for q < p) + s``.

    Examples
    --------
    >>> import numpy as np
    >>> both = concat_packs([pack_convex([np.eye(3)]), pack_convex([np.eye(3) + 1.0])])
    >>> both.starts.tolist()
    [0, 3, 6]
    """
    point_off = 0
    edge_off = 0
    points, starts, nbr_starts, nbrs, lower, upper = [], [np.zeros(1, np.int64)], [], [], [], []
    nbr_starts.append(np.zeros(1, np.int64))
    for pack in packs:
        points.append(pack.points)
        starts.append(pack.starts[1:] + point_off)
        nbr_starts.append(pack.nbr_starts[1:] + edge_off)
        nbrs.append(pack.nbrs + point_off)
        lower.append(pack.lower)
        upper.append(pack.upper)
        point_off += pack.points.shape[0]
        edge_off += pack.nbrs.shape[0]

    def cat(parts, shape, dtype):
        if not parts:
            return np.empty(shape, dtype=dtype)
        return np.ascontiguousarray(np.concatenate(parts), dtype=dtype)

    return ConvexPack(
        cat(points, (0, 3), np.float64),
        cat(starts, (1,), np.int64),
        cat(nbr_starts, (1,), np.int64),
        cat(nbrs, (0,), np.int64),
        cat(lower, (0, 3), np.float64),
        cat(upper, (0, 3), np.float64),
    )


def repeat_pack(
    pack: ConvexPack, points: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> ConvexPack:
    """``pack``'s shapes ``E`` times over, copy ``k`` at new coordinates: a pack moved rigidly
    to ``E`` placements (its hull adjacency does not change).

    Parameters
    ----------
    pack : ConvexPack
        ``m`` shapes, ``N`` points.
    points : (E, N, 3) float64
        Each copy's points, in ``pack.points``' order.
    lower, upper : (E, m, 3) float64
        Each copy's shape bounding boxes.

    Returns
    -------
    ConvexPack
        Shape ``s`` of copy ``k`` is shape ``k * m + s``.

    Examples
    --------
    >>> import numpy as np
    >>> pack = pack_convex([np.eye(3)])
    >>> moved = np.stack([pack.points, pack.points + 1.0])
    >>> twice = repeat_pack(pack, moved, moved.min(axis=1)[:, None], moved.max(axis=1)[:, None])
    >>> twice.starts.tolist(), twice.lower.tolist()
    ([0, 3, 6], [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    """
    count, n, edges = len(points), len(pack.points), len(pack.nbrs)
    copies = np.arange(count, dtype=np.int64)[:, None]
    starts = np.concatenate([(pack.starts[:-1][None, :] + n * copies).ravel(), [n * count]])
    nbr_starts = np.concatenate(
        [(pack.nbr_starts[:-1][None, :] + edges * copies).ravel(), [edges * count]]
    )
    nbrs = (pack.nbrs[None, :] + n * copies).ravel()
    return ConvexPack(
        points.reshape(-1, 3),
        starts.astype(np.int64),
        nbr_starts.astype(np.int64),
        nbrs,
        lower.reshape(-1, 3),
        upper.reshape(-1, 3),
    )


def support_points(points: np.ndarray) -> np.ndarray:
    """Points whose convex hull is the convex hull of ``points``, as cheaply as a support map
    allows: all of them when a scan would read them anyway (``HILL_CLIMB_MIN_VERTICES`` or
    fewer), else the hull's vertices (Qhull; every point when the hull is flat), in index order.

    Parameters
    ----------
    points : (n, 3) float64

    Returns
    -------
    (k, 3) float64
    """
    points = np.asarray(points, dtype=np.float64)
    if len(points) <= HILL_CLIMB_MIN_VERTICES:
        return points
    try:
        return points[np.sort(ConvexHull(points).vertices)]
    except (QhullError, ValueError):
        return points


def place_packs(
    packs: Sequence[ConvexPack],
    which: np.ndarray,
    transforms: np.ndarray,
    shifts: np.ndarray | None = None,
) -> ConvexPack:
    """Copies of frame-local packs, each placed in the world: ``packs`` built once per distinct
    geometry, moved to every part that has it (a placement keeps a hull's adjacency).

    Parameters
    ----------
    packs : sequence of ConvexPack
        Shapes in their own frames.
    which : (n,) int64
        The pack of each copy.
    transforms : (n, 4, 4) float64
        Frame -> world of each copy.
    shifts : (n, 3) float64, optional
        Added to a copy's points before its transform (a mesh's corner); default 0.

    Returns
    -------
    ConvexPack
        The shapes of copy 0, then copy 1..., each copy's points ``(p + shift) @ R.T + t``
        (``p + shift`` for an identity transform).

    Examples
    --------
    >>> import numpy as np
    >>> up = np.eye(4)
    >>> up[2, 3] = 5.0
    >>> pack = pack_convex([np.eye(3)])
    >>> placed = place_packs([pack], np.array([0, 0]), np.stack([np.eye(4), up]))
    >>> placed.starts.tolist(), placed.lower.tolist()
    ([0, 3, 6], [[0.0, 0.0, 0.0], [0.0, 0.0, 5.0]])
    """
    which = np.asarray(which, dtype=np.int64).reshape(-1)
    transforms = np.asarray(transforms, dtype=np.float64).reshape(-1, 4, 4)
    n = len(which)
    shifts = np.zeros((n, 3)) if shifts is None else np.asarray(shifts, dtype=np.float64)
    n_points = np.array([len(p.points) for p in packs], dtype=np.int64)[which]
    n_shapes = np.array([len(p.starts) - 1 for p in packs], dtype=np.int64)[which]
    n_edges = np.array([len(p.nbrs) for p in packs], dtype=np.int64)[which]
    point_at = np.concatenate([[0], np.cumsum(n_points)]).astype(np.int64)
    shape_at = np.concatenate([[0], np.cumsum(n_shapes)]).astype(np.int64)
    edge_at = np.concatenate([[0], np.cumsum(n_edges)]).astype(np.int64)
    points = np.empty((point_at[-1], 3))
    starts = np.empty(shape_at[-1] + 1, dtype=np.int64)
    nbr_starts = np.empty(point_at[-1] + 1, dtype=np.int64)
    nbrs = np.empty(edge_at[-1], dtype=np.int64)
    order = np.argsort(which, kind="stable")
    bounds = np.searchsorted(which[order], np.arange(len(packs) + 1))
    for g, pack in enumerate(packs):
        copies = order[bounds[g] : bounds[g + 1]]
        if not len(copies):
            continue
        local = pack.points[None, :, :] + shifts[copies][:, None, :]
        moved = local @ np.transpose(transforms[copies, :3, :3], (0, 2, 1))
        moved += transforms[copies, None, :3, 3]
        still = np.all(transforms[copies] == np.eye(4), axis=(1, 2))
        moved[still] = local[still]
        rows = point_at[copies][:, None] + np.arange(len(pack.points))
        points[rows] = moved
        nbr_starts[rows] = edge_at[copies][:, None] + pack.nbr_starts[None, :-1]
        shape_rows = shape_at[copies][:, None] + np.arange(len(pack.starts) - 1)
        starts[shape_rows] = point_at[copies][:, None] + pack.starts[None, :-1]
        edge_rows = edge_at[copies][:, None] + np.arange(len(pack.nbrs))
        nbrs[edge_rows] = point_at[copies][:, None] + pack.nbrs[None, :]
    starts[-1] = point_at[-1]
    nbr_starts[-1] = edge_at[-1]
    if shape_at[-1]:
        lower = np.minimum.reduceat(points, starts[:-1], axis=0)
        upper = np.maximum.reduceat(points, starts[:-1], axis=0)
    else:
        lower = upper = np.empty((0, 3), dtype=np.float64)
    return ConvexPack(points, starts, nbr_starts, nbrs, lower, upper)


def farthest_from_lines(
    points: np.ndarray, placed: np.ndarray, origins: np.ndarray, directions: np.ndarray
) -> np.ndarray:
    """The largest distance of a few points, rigidly placed E times, from T lines each time.

    Parameters
    ----------
    points : (k, 3) float64
        In their own frame.
    placed : (E, 4, 4) float64
        Each placement of that frame.
    origins, directions : (E, T, 3) float64
        A point on each line and its unit direction, per placement.

    Returns
    -------
    (E, T) float64
        ``max_p |(p - o) - ((p - o) . u) u|`` over the placed points; ``inf`` where that is
        not a number.

    Examples
    --------
    >>> import numpy as np
    >>> z_axis = np.array([[[0.0, 0.0, 0.0]]]), np.array([[[0.0, 0.0, 1.0]]])
    >>> farthest_from_lines(np.array([[3.0, 4.0, 7.0]]), np.eye(4)[None], *z_axis)
    array([[5.]])
    """
    f8 = np.float64
    return _kernels.hull_levers(
        np.ascontiguousarray(points, f8),
        np.ascontiguousarray(placed, f8),
        np.ascontiguousarray(origins, f8),
        np.ascontiguousarray(directions, f8),
    )
