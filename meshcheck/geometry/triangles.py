"""Exact triangle-triangle distance, the triangle pairs of two meshes within reach, and points
against a whole mesh (winding numbers, distances, the inscribed ball): the verify stage.

Every function takes vertices ``(n, 3) float64`` and faces ``(m, 3) int64`` in a frame the caller
has re-centred near the region of interest, so coordinates far from the origin keep their digits.
The work is C++ (``src/triangles.hpp``, compiled at ``pip install``); these functions check and
convert their arguments (other dtypes are converted, face indices are checked against the
vertices) and raise ``ValueError`` on malformed input.
"""

from __future__ import annotations

import numpy as np

from . import _kernels

__all__ = [
    "box_pairs",
    "closest_points_on_triangles",
    "inscribed_ball",
    "near_triangle_pairs",
    "pair_distances",
    "placed_surface_distance",
    "point_distances",
    "ray_hits",
    "triangle_boxes",
    "triangle_distance",
    "winding_numbers",
]


def _f8(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float64)


def _i8(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.int64)


def triangle_distance(a0, a1, a2, b0, b1, b2):
    """Exact distance between triangles ``a0 a1 a2`` and ``b0 b1 b2``, with witness points.

    Parameters
    ----------
    a0, a1, a2, b0, b1, b2 : (3,) array-like of float
        Corners of each triangle.

    Returns
    -------
    distance : float
        0 when the triangles meet.
    point_a, point_b : tuple of 3 floats
        Closest points on each triangle (the same point when an edge crosses the other triangle).
    crossing : bool
        True when an edge of one passes strictly through the interior of the other.

    Examples
    --------
    >>> triangle_distance((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 2), (1, 0, 2), (0, 1, 2))[0]
    2.0
    """
    return _kernels.triangle_distance(*(_f8(p) for p in (a0, a1, a2, b0, b1, b2)))


def triangle_boxes(v, f) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned boxes of triangles: ``lower, upper``, each ``(m, 3) float64``."""
    return _kernels.triangle_boxes(_f8(v), _i8(f))


def box_pairs(alo, ahi, blo, bhi, reach: float) -> np.ndarray:
    """Pairs ``(i, j)`` of boxes of two sets whose gap is at most ``reach`` along every axis.

    A median-split bounding-volume hierarchy over the second set, queried with each box of the
    first.

    Parameters
    ----------
    alo, ahi : (ma, 3) float64
    blo, bhi : (mb, 3) float64
    reach : float

    Returns
    -------
    pairs : (k, 2) int64
        Index into the first set, index into the second.
    """
    return _kernels.box_pairs(_f8(alo), _f8(ahi), _f8(blo), _f8(bhi), float(reach))


def near_triangle_pairs(va, fa, vb, fb, relative, reach: float) -> np.ndarray:
    """The triangle pairs of two meshes, ``b`` placed in ``a``'s frame by ``relative``, whose
    boxes come within ``reach`` of each other along every axis (``box_pairs``, with ``b``'s
    triangles placed and only those near the other mesh's box paired).

    Parameters
    ----------
    va, vb : (n, 3) float64
        Vertices, each mesh's own frame.
    fa, fb : (m, 3) int64
    relative : (4, 4) float64
        ``b``'s frame into ``a``'s; ``ValueError`` when not finite.
    reach : float

    Returns
    -------
    pairs : (k, 2) int64
        Face of ``a``, face of ``b``.

    Examples
    --------
    >>> import numpy as np
    >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    >>> up = np.eye(4)
    >>> up[2, 3] = 0.5
    >>> near_triangle_pairs(tri, [[0, 1, 2]], tri, [[0, 1, 2]], up, 0.5).tolist()
    [[0, 0]]
    >>> near_triangle_pairs(tri, [[0, 1, 2]], tri, [[0, 1, 2]], up, 0.4).tolist()
    []
    """
    return _kernels.near_triangle_pairs(
        _f8(va), _i8(fa), _f8(vb), _i8(fb), _f8(relative), float(reach)
    )


def placed_surface_distance(
    va, fa, vb, fb, relative, reach: float, *, settle: bool = False
) -> tuple[float, int]:
    """The distance between two meshes, ``b`` placed in ``a``'s frame by ``relative``.

    Only the triangles of each mesh whose boxes come within ``reach`` of the other's are
    paired (a hierarchy over ``b``'s), and the pairs whose boxes come within ``reach`` are
    measured exactly, nearest boxes first. 0 where the surfaces cross.

    Parameters
    ----------
    va, vb : (n, 3) float64
        Vertices, each mesh's own frame.
    fa, fb : (m, 3) int64
    relative : (4, 4) float64
        ``b``'s frame into ``a``'s.
    reach : float
    settle : bool, keyword-only
        Only whether the meshes come within ``reach`` matters: the first pair within it
        answers.

    Returns
    -------
    distance : float
        Exact when at most ``reach`` (with ``settle``: some pair's distance within it);
        otherwise a value above ``reach`` (``inf`` when no pair's boxes come within it);
        ``-inf`` when ``relative`` or ``reach`` is not a number.
    pairs : int
        Triangle pairs measured.

    Examples
    --------
    >>> import numpy as np
    >>> tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    >>> up = np.eye(4)
    >>> up[2, 3] = 0.5
    >>> placed_surface_distance(tri, [[0, 1, 2]], tri, [[0, 1, 2]], up, 1.0)
    (0.5, 1)
    """
    return _kernels.placed_surface_distance(
        _f8(va), _i8(fa), _f8(vb), _i8(fb), _f8(relative), float(reach), bool(settle)
    )


def pair_distances(va, fa, vb, fb, pairs):
    """Exact distance of each triangle pair, in one compiled loop.

    Parameters
    ----------
    va, vb : (n, 3) float64
        Vertices of each mesh, common frame.
    fa, fb : (m, 3) int64
        Faces of each mesh.
    pairs : (k, 2) int64
        Face of ``a``, face of ``b``.

    Returns
    -------
    distance : (k,) float64
    point_a, point_b : (k, 3) float64
        Closest points.
    strength : (k,) float64
        For pairs whose edges pass through each other's interiors, how far the triangles reach
        through each other: the least of the four reaches of one triangle beyond the other's
        plane, on either side (near 0 for faces resting on faces); 0 for pairs that do not cross.
    """
    return _kernels.pair_distances(_f8(va), _i8(fa), _f8(vb), _i8(fb), _i8(pairs))


def winding_numbers(points, v, f) -> np.ndarray:
    """Generalized winding number of each point (1 inside a closed outward mesh, 0 outside).

    Van Oosterom and Strackee's solid angle of each triangle, summed over ``4 pi``.
    """
    return _kernels.winding_numbers(_f8(points), _f8(v), _i8(f))


def point_distances(points, v, f) -> np.ndarray:
    """Unsigned distance from each point ``(k, 3)`` to the nearest triangle of ``(v, f)``."""
    return _kernels.point_distances(_f8(points), _f8(v), _i8(f))


def inscribed_ball(v, f, max_seeds: int) -> tuple[float, tuple[float, float, float]]:
    """Largest ball inside a closed, outward-wound mesh: ``(radius, centre 3-tuple)``.

    Seeds: from the centroid of (up to ``max_seeds``, evenly strided) faces, a ray along the inward
    normal to the first surface it meets; its midpoint is inside the solid, on the medial surface
    of any slab or shell. The best seeds are refined by a compass search over 26 directions whose
    step never exceeds the current radius, so every accepted point stays inside the solid.
    """
    return _kernels.inscribed_ball(_f8(v), _i8(f), int(max_seeds))


def ray_hits(o, d, v, f, beyond: float) -> np.ndarray:
    """Distance along each ray ``o + t d`` (origins and directions ``(r, 3)``) to the first
    triangle of ``(v, f)`` it meets at ``t > beyond`` (Moller-Trumbore), ``inf`` when none:
    ``(r,) float64``."""
    return _kernels.ray_hits(_f8(o), _f8(d), _f8(v), _i8(f), float(beyond))


def closest_points_on_triangles(p, v, f) -> tuple[np.ndarray, np.ndarray]:
    """Distance from point ``p (3,)`` to every triangle, and the closest points ``(m, 3)``."""
    return _kernels.closest_points_on_triangles(_f8(p), _f8(v), _i8(f))
