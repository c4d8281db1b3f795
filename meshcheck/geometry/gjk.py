"""GJK on convex hulls: status, signed distance, witness points and normal.

The classic Gilbert-Johnson-Keerthi iteration on the Minkowski difference ``D = A - B``: the
shapes meet iff ``D`` holds the origin, and their distance is the distance from the origin to
``D``. Each iteration asks for the support point of ``D`` towards the origin and replaces the
simplex by the smallest face of (simplex + new point) nearest the origin, by one small function
per simplex size (``do_simplex2/3/4``, as libccd).

Like parry, the iteration keeps two bounds on the signed distance ``sd``:

* ``upper = |v|``, where ``v`` is the simplex point nearest the origin (a point of ``D``);
* ``lower = max over iterations of (w . v) / |v|`` for the support point ``w`` along ``-v``:
  ``D`` lies in the half-space ``{x : x . v/|v| >= lower}``. This is a bound on the *signed*
  distance, negative when the shapes overlap.

and the answer follows from them against the tolerance ``tol``:

* ``lower > tol``                          -> SEPARATED (distance ``upper`` once converged);
* ``upper <= tol and lower >= -tol``       -> TOUCHING (so a "distance 0" always rests on one
  more support point than the simplex that produced it, as MuJoCo's fix for false zeros);
* the origin on or inside the simplex      -> :mod:`meshcheck.geometry.epa` (depth);
* neither after ``GJK_MAX_ITER``           -> UNDECIDED, never SEPARATED.

Both shapes are re-centred on a common point before iterating (Bullet), so parts 1e5 units from
the origin keep their digits. Every Minkowski point keeps its two source points, which give the
witness points.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import get_num_threads, njit, prange, types

from .constants import (
    COORD_REL,
    DEGENERATE_SIN,
    GJK_MAX_ITER,
    GJK_REL_GAP,
    PARALLEL_MIN_PAIRS,
    SEPARATED,
    TOUCH_REL,
    TOUCHING,
    UNDECIDED,
    ZERO_REL,
)
from .epa import closest_on_segment, closest_on_triangle, contact, epa_workspace, write_answer
from .support import B1, F1D, F2D, F8, I1D, I2D, I8, SHAPE, ConvexPack, cso_support

__all__ = [
    "Contact",
    "PairQuery",
    "Status",
    "intersects",
    "query",
    "query_pairs",
    "signed_distance",
]


class Status(enum.IntEnum):
    """How two convex shapes relate, given a tolerance."""

    SEPARATED = 0
    """The distance exceeds the tolerance."""
    TOUCHING = 1
    """The signed distance is within the tolerance of 0."""
    PENETRATING = 2
    """The shapes overlap by more than the tolerance."""
    UNDECIDED = 3
    """Iteration limit or numerical trouble; treat as "maybe meeting". Never NaN."""


@dataclass(frozen=True, eq=False)
class Contact:
    """The answer of :func:`query` for one pair of convex shapes.

    Attributes
    ----------
    status : Status
    distance : float
        Signed distance, model units: > 0 the gap, < 0 minus the penetration depth, near 0
        when touching. For UNDECIDED a lower bound of the signed distance (0.0 if none).
    point_a : (3,) float64
        Witness point on A, world coordinates: the closest point; when penetrating, the
        deepest point of A inside B along ``normal``.
    point_b : (3,) float64
        Witness point on B. ``point_b - point_a == distance * normal`` up to rounding.
    normal : (3,) float64
        Unit vector from A toward B: the direction along the gap, or the direction to move B
        by ``-distance`` to separate the shapes.
    """

    status: Status
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray


class PairQuery(NamedTuple):
    """The answers of :func:`query_pairs`, one row per pair.

    Attributes
    ----------
    status : (k,) int8
        :class:`Status` codes.
    distance : (k,) float64
        Signed distances, model units (see :func:`query_pairs` for the early exits).
    point_a, point_b : (k, 3) float64
        Witness points, world coordinates.
    normal : (k, 3) float64
        Unit normals from A toward B.
    """

    status: np.ndarray
    distance: np.ndarray
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray


# ---------------------------------------------------------------------------------------------
# Simplex cases
# ---------------------------------------------------------------------------------------------


@njit(I8(F2D, F2D, F2D, I2D, F1D, I8), cache=True, nogil=True)
def _compact(W, SA, SB, IX, lam, k):
    """Drop simplex points of zero weight, keeping order; return the new size."""
    n = 0
    for r in range(k):
        if lam[r] > 0.0:
            if n != r:
                for c in range(3):
                    W[n, c] = W[r, c]
                    SA[n, c] = SA[r, c]
                    SB[n, c] = SB[r, c]
                IX[n, 0] = IX[r, 0]
                IX[n, 1] = IX[r, 1]
                lam[n] = lam[r]
            n += 1
    return n


@njit(I8(F2D, F2D, F2D, I2D, F1D), cache=True, nogil=True)
def do_simplex2(W, SA, SB, IX, lam):
    """Segment: keep the vertex or the segment nearest the origin. Returns the new size."""
    lam[0], lam[1] = closest_on_segment(W, 0, 1)
    return _compact(W, SA, SB, IX, lam, 2)


@njit(I8(F2D, F2D, F2D, I2D, F1D), cache=True, nogil=True)
def do_simplex3(W, SA, SB, IX, lam):
    """Triangle: keep the vertex, edge or face nearest the origin. Returns the new size."""
    lam[0], lam[1], lam[2] = closest_on_triangle(W, 0, 1, 2)
    return _compact(W, SA, SB, IX, lam, 3)


@njit(types.Tuple((I8, B1))(F2D, F2D, F2D, I2D, F1D), cache=True, nogil=True)
def do_simplex4(W, SA, SB, IX, lam):
    """Tetrahedron: detect that it holds the origin, else keep its feature nearest the origin.

    Returns ``(size, encloses)``. A tetrahedron whose volume is below ``DEGENERATE_SIN`` times
    the product of its edges is flat: orientation tests on it are noise, so its nearest point is
    found over all four faces and it never claims to enclose the origin.
    """
    e1x, e1y, e1z = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
    e2x, e2y, e2z = W[2, 0] - W[0, 0], W[2, 1] - W[0, 1], W[2, 2] - W[0, 2]
    e3x, e3y, e3z = W[3, 0] - W[0, 0], W[3, 1] - W[0, 1], W[3, 2] - W[0, 2]
    det = (
        e1x * (e2y * e3z - e2z * e3y)
        + e1y * (e2z * e3x - e2x * e3z)
        + e1z * (e2x * e3y - e2y * e3x)
    )
    scale = np.sqrt(
        (e1x * e1x + e1y * e1y + e1z * e1z)
        * (e2x * e2x + e2y * e2y + e2z * e2z)
        * (e3x * e3x + e3y * e3y + e3z * e3z)
    )
    flat = abs(det) <= DEGENERATE_SIN * scale
    best = np.inf
    bi, bj, bm, wi, wj, wm = 0, 1, 2, 1.0, 0.0, 0.0
    encloses = True
    for f in range(4):
        # Face (i, j, m) opposite vertex o.
        if f == 0:
            i, j, m, o = 0, 1, 2, 3
        elif f == 1:
            i, j, m, o = 0, 1, 3, 2
        elif f == 2:
            i, j, m, o = 0, 2, 3, 1
        else:
            i, j, m, o = 1, 2, 3, 0
        if not flat:
            abx, aby, abz = W[j, 0] - W[i, 0], W[j, 1] - W[i, 1], W[j, 2] - W[i, 2]
            acx, acy, acz = W[m, 0] - W[i, 0], W[m, 1] - W[i, 1], W[m, 2] - W[i, 2]
            nx = aby * acz - abz * acy
            ny = abz * acx - abx * acz
            nz = abx * acy - aby * acx
            s_origin = -(nx * W[i, 0] + ny * W[i, 1] + nz * W[i, 2])
            s_opp = nx * (W[o, 0] - W[i, 0]) + ny * (W[o, 1] - W[i, 1]) + nz * (W[o, 2] - W[i, 2])
            if s_origin * s_opp >= 0.0:
                continue  # the origin is on the tetrahedron's side of this face
        encloses = False
        li, lj, lm = closest_on_triangle(W, i, j, m)
        px = li * W[i, 0] + lj * W[j, 0] + lm * W[m, 0]
        py = li * W[i, 1] + lj * W[j, 1] + lm * W[m, 1]
        pz = li * W[i, 2] + lj * W[j, 2] + lm * W[m, 2]
        d = px * px + py * py + pz * pz
        if d < best:
            best = d
            bi, bj, bm, wi, wj, wm = i, j, m, li, lj, lm
    if encloses:
        return 4, True
    lam[0] = lam[1] = lam[2] = lam[3] = 0.0
    lam[bi], lam[bj], lam[bm] = wi, wj, wm
    return _compact(W, SA, SB, IX, lam, 4), False


# ---------------------------------------------------------------------------------------------
# GJK
# ---------------------------------------------------------------------------------------------


@njit(types.none(I8, F8, I8, F2D, F2D, F1D, F8, F8, F8, F1D, F1D), cache=True, nogil=True)
def _answer_simplex(status, distance, k, SA, SB, lam, nx, ny, nz, centre, out):
    ax = ay = az = bx = by = bz = 0.0
    for r in range(k):
        ax += lam[r] * SA[r, 0]
        ay += lam[r] * SA[r, 1]
        az += lam[r] * SA[r, 2]
        bx += lam[r] * SB[r, 0]
        by += lam[r] * SB[r, 1]
        bz += lam[r] * SB[r, 2]
    write_answer(out, status, distance, ax, ay, az, bx, by, bz, nx, ny, nz, centre)


@njit(types.UniTuple(F8, 3)(F2D, F1D, I8), cache=True, nogil=True)
def _nearest_point(W, lam, k):
    """The simplex point ``v`` nearest the origin.

    For a triangle it is the origin's projection on the plane, ``n (n . a) / |n|^2`` with the
    normal ``n`` from a cross product of edges (as libccd's doSimplex3 takes the normal as the
    new direction): when the shapes nearly touch, ``v`` is tiny next to the simplex points and
    ``sum(lam * W)`` would give its direction only to ``eps |W| / |v|`` (1e-6 at a 1e-10 gap),
    while the normal keeps full precision, and with it the lower bound ``w . v / |v|``.

    For a segment ``e`` the same holds for the component of ``v`` along ``e``: it is projected
    out once more, so ``v`` is square to ``e`` to ``eps |v|`` and both ends of a long thin
    Minkowski difference give the same, accurate bound (nearly collinear segments 1e-10 apart).
    """
    if k == 3:
        abx, aby, abz = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
        acx, acy, acz = W[2, 0] - W[0, 0], W[2, 1] - W[0, 1], W[2, 2] - W[0, 2]
        nx = aby * acz - abz * acy
        ny = abz * acx - abx * acz
        nz = abx * acy - aby * acx
        nn = nx * nx + ny * ny + nz * nz
        if nn > 0.0:
            s = (nx * W[0, 0] + ny * W[0, 1] + nz * W[0, 2]) / nn
            return nx * s, ny * s, nz * s
    vx = vy = vz = 0.0
    for r in range(k):
        vx += lam[r] * W[r, 0]
        vy += lam[r] * W[r, 1]
        vz += lam[r] * W[r, 2]
    if k == 2:
        ex, ey, ez = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
        ee = ex * ex + ey * ey + ez * ez
        if ee > 0.0:
            s = (vx * ex + vy * ey + vz * ez) / ee
            vx, vy, vz = vx - s * ex, vy - s * ey, vz - s * ez
    return vx, vy, vz


_SIMPLEX = (F2D, F2D, F2D, I2D, F1D)  # W, SA, SB, IX, lam


@njit(I8(*SHAPE, *SHAPE, F1D, F1D, F8, F8, F8, *_SIMPLEX, F1D), cache=True, nogil=True)
def gjk(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b,
        centre, guess, size, tol, max_distance, W, SA, SB, IX, lam, out):  # fmt: skip
    """Run GJK on one pair; answer into ``out``, or hand over to EPA when the shapes meet.

    Parameters
    ----------
    pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b
        The two shapes, as for :func:`meshcheck.geometry.support.cso_support`.
    centre : (3,) float64
        Common centre both shapes are re-centred on, world coordinates.
    guess : (3,) float64
        First search direction, from A toward B (e.g. centre of B minus centre of A).
    size : float64
        Size of the query (largest AABB edge of the two shapes), model units.
    tol : float64
        Touching tolerance, model units, >= 0.
    max_distance : float64
        Stop with SEPARATED as soon as the distance is known to exceed it (and ``tol``); the
        distance is then that lower bound. ``inf`` to always converge.
    W, SA, SB : (4, 3) float64
        Work arrays: simplex points of ``A - B`` and their sources on A and B (re-centred).
    IX : (4, 2) int64
        Work array: source vertex indices.
    lam : (>= 4,) float64
        Work array: barycentric weights.
    out : (11,) float64
        ``[status, distance, point_a(3), point_b(3), normal(3)]``.

    Returns
    -------
    int
        0 when ``out`` holds the answer; else the size of the simplex (in ``W, SA, SB, IX,
        lam``) that holds the origin, for :func:`meshcheck.geometry.epa.contact`. (The caller
        makes that call: with it inside this loop numba's code for the loop ran ~2x slower.)
    """
    zero_eps = min(ZERO_REL * size, 0.5 * tol)
    ia, ib = cso_support(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1,
                         climb_b, centre, guess[0], guess[1], guess[2], a0, b0)  # fmt: skip
    for c in range(3):
        SA[0, c] = pts_a[ia, c] - centre[c]
        SB[0, c] = pts_b[ib, c] - centre[c]
        W[0, c] = SA[0, c] - SB[0, c]
    IX[0, 0], IX[0, 1] = ia, ib
    lam[0] = 1.0
    k = 1
    vx, vy, vz = W[0, 0], W[0, 1], W[0, 2]
    lower = -np.inf
    upper = np.sqrt(vx * vx + vy * vy + vz * vz)

    for _ in range(GJK_MAX_ITER):
        if upper <= zero_eps:
            return k  # the origin is on the simplex: the shapes meet
        ia, ib = cso_support(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1,
                             climb_b, centre, -vx, -vy, -vz, ia, ib)  # fmt: skip
        wax, way, waz = pts_a[ia, 0] - centre[0], pts_a[ia, 1] - centre[1], pts_a[ia, 2] - centre[2]
        wbx, wby, wbz = pts_b[ib, 0] - centre[0], pts_b[ib, 1] - centre[1], pts_b[ib, 2] - centre[2]
        wx, wy, wz = wax - wbx, way - wby, waz - wbz
        lb = (wx * vx + wy * vy + wz * vz) / upper
        if lb > lower:
            lower = lb
        if lower > tol and lower > max_distance:
            _answer_simplex(SEPARATED, lower, k, SA, SB, lam, -vx, -vy, -vz, centre, out)
            return 0
        if upper - lower <= GJK_REL_GAP * upper:
            break  # converged
        if upper <= tol and lower >= -tol:
            break  # touching: |signed distance| <= tol, on the word of a fresh support point
        repeated = False
        for r in range(k):
            if IX[r, 0] == ia and IX[r, 1] == ib:
                repeated = True
        if repeated:
            break  # no new point: converged up to rounding
        W[k, 0], W[k, 1], W[k, 2] = wx, wy, wz
        SA[k, 0], SA[k, 1], SA[k, 2] = wax, way, waz
        SB[k, 0], SB[k, 1], SB[k, 2] = wbx, wby, wbz
        IX[k, 0], IX[k, 1] = ia, ib
        k += 1
        if k == 2:
            k = do_simplex2(W, SA, SB, IX, lam)
        elif k == 3:
            k = do_simplex3(W, SA, SB, IX, lam)
        else:
            k, encloses = do_simplex4(W, SA, SB, IX, lam)
            if encloses:
                return k  # the tetrahedron holds the origin: the shapes meet
        vx, vy, vz = _nearest_point(W, lam, k)
        new_upper = np.sqrt(vx * vx + vy * vy + vz * vz)
        stalled = new_upper >= upper
        upper = new_upper
        if stalled:
            break  # no progress (rounding): decide from the bounds

    if lower > tol:
        status = SEPARATED
        distance = upper
    elif upper <= tol and lower >= -tol:
        status = TOUCHING
        distance = upper if lower >= 0.0 else 0.0
    elif upper - lower <= GJK_REL_GAP * upper:
        # Converged, with the tolerance inside the (tiny) bracket: the estimate decides.
        status = SEPARATED if upper > tol else TOUCHING
        distance = upper
    elif upper <= tol:
        # The origin is within tol of the simplex but no direction has shown the far side of
        # D within tol (a flat or sliver D). Let the blow-up and EPA look for one: their
        # TOUCHING / PENETRATING verdicts rest on bounds that hold wherever the origin is.
        return k
    else:
        status = UNDECIDED
        distance = lower if np.isfinite(lower) else 0.0
    _answer_simplex(status, distance, k, SA, SB, lam, -vx, -vy, -vz, centre, out)
    return 0


@njit(types.Tuple((F2D, F2D, F2D, F2D, F1D, F1D, F1D, I2D, I1D))(), cache=True, nogil=True)
def _workspace():
    """Work arrays of one GJK query, carved from two allocations (each costs ~0.1 us)."""
    f = np.empty((20, 3))
    idx = np.zeros((5, 2), dtype=np.int64)
    # W, SA, SB, box (lo_a, hi_a, lo_b, hi_b), centre, guess, lam; IX, an empty adjacency
    lam = f[18:20].reshape(6)
    return f[0:4], f[4:8], f[8:12], f[12:16], f[16], f[17], lam, idx[0:4], idx[4]


@njit(B1(F2D, F1D, F1D), cache=True, nogil=True)
def _bounds(pts, lo, hi):
    """Fill the AABB ``lo, hi`` of ``pts``; return False if a coordinate is not finite."""
    for c in range(3):
        lo[c] = np.inf
        hi[c] = -np.inf
    for i in range(pts.shape[0]):
        for c in range(3):
            x = pts[i, c]
            if x < lo[c]:
                lo[c] = x
            if x > hi[c]:
                hi[c] = x
    for c in range(3):
        if not (np.isfinite(lo[c]) and np.isfinite(hi[c])):
            return False
    return True


@njit(types.UniTuple(F8, 2)(F2D, F8, F1D, F1D), cache=True, nogil=True)
def _setup(box, tol, centre, guess):
    """Fill the common centre and first direction; return ``(size, tol)`` (default if tol < 0).

    ``box`` is (4, 3): the AABB minimum and maximum of A, then of B.
    """
    size = 0.0
    coord = 0.0
    gl = 0.0
    for c in range(3):
        ca = 0.5 * (box[0, c] + box[1, c])
        cb = 0.5 * (box[2, c] + box[3, c])
        centre[c] = 0.5 * (ca + cb)
        guess[c] = cb - ca
        gl += guess[c] * guess[c]
        size = max(size, box[1, c] - box[0, c], box[3, c] - box[2, c])
        coord = max(coord, abs(box[0, c]), abs(box[1, c]), abs(box[2, c]), abs(box[3, c]))
    if gl == 0.0:
        guess[0], guess[1], guess[2] = 1.0, 0.0, 0.0
    if tol < 0.0:
        tol = max(TOUCH_REL * size, COORD_REL * coord)
    return size, tol


@njit(types.none(F2D, F2D, F8, B1, F1D), cache=True, nogil=True)
def _query_points(a, b, tol, want_depth, out):
    """Compiled body of :func:`query`: linear-scan supports on the raw points, no hull.

    Writes the answer into ``out`` (11,) float64; ``out[0] = -1`` for non-finite input. (The
    caller allocates ``out``: numba returning a new array costs ~1 us per call.)
    """
    W, SA, SB, box, centre, guess, lam, IX, no_adj = _workspace()
    if not (_bounds(a, box[0], box[1]) and _bounds(b, box[2], box[3])):
        out[0] = -1.0
        return
    size, tol = _setup(box, tol, centre, guess)
    n, m = a.shape[0], b.shape[0]
    k = gjk(a, no_adj, no_adj, 0, n, False, b, no_adj, no_adj, 0, m, False,
            centre, guess, size, tol, np.inf, W, SA, SB, IX, lam, out)  # fmt: skip
    if k > 0:
        fws, iws = epa_workspace()
        contact(a, no_adj, no_adj, 0, n, False, b, no_adj, no_adj, 0, m, False,
                centre, size, tol, want_depth, k, W, SA, SB, IX, lam, fws, iws, out)  # fmt: skip


def _contiguous(x, dtype) -> np.ndarray:
    """``x`` as a C-contiguous, writable array of ``dtype``, copied only if needed.

    The kernels are compiled for exactly these array types; a read-only or strided array would
    cost one more compilation (seconds) and one more cache entry.
    """
    arr = np.ascontiguousarray(x, dtype=dtype)
    return arr if arr.flags.writeable else arr.copy()


def _points(x, name: str) -> np.ndarray:
    if (
        type(x) is np.ndarray
        and x.dtype == np.float64
        and x.ndim == 2
        and x.shape[1] == 3
        and x.shape[0] > 0
        and x.flags.c_contiguous
        and x.flags.writeable
    ):
        return x
    arr = _contiguous(x, np.float64)
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ValueError(f"{name}: expected an (n, 3) array of points with n >= 1, got {arr.shape}")
    return arr


def _tolerance(tolerance) -> float:
    if tolerance is None:
        return -1.0
    tol = float(tolerance)
    if not tol >= 0.0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")
    return tol


def _run(a, b, tolerance, want_depth: bool) -> np.ndarray:
    out = np.empty(11)
    _query_points(_points(a, "a"), _points(b, "b"), _tolerance(tolerance), want_depth, out)
    if out[0] < 0.0:
        raise ValueError("a, b: coordinates must be finite")
    return out


def query(a, b, *, tolerance: float | None = None) -> Contact:
    """Relate two convex hulls: status, signed distance, witness points and normal.

    Parameters
    ----------
    a, b : (n, 3) array-like of float
        Points in world coordinates, model units, each taken as its convex hull (n >= 1: a
        point, segment, flat polygon or solid). No hull is computed: the support map scans
        the points, so any extra interior points only cost time.
    tolerance : float, optional, keyword-only
        Touching tolerance, absolute, model units. Default: ``TOUCH_REL`` times the larger AABB
        edge of the two shapes, at least ``COORD_REL`` times their largest coordinate (see
        :mod:`meshcheck.geometry.constants`).

    Returns
    -------
    Contact

    Raises
    ------
    ValueError
        A shape is not an (n, 3) array with n >= 1, has non-finite coordinates, or the
        tolerance is negative.

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> c = query(cube, cube + [3.0, 0.0, 0.0])
    >>> c.status.name, round(c.distance, 12), c.normal.tolist()
    ('SEPARATED', 2.0, [1.0, 0.0, 0.0])
    """
    out = _run(a, b, tolerance, True)
    return Contact(
        Status(int(out[0])), float(out[1]), out[2:5].copy(), out[5:8].copy(), out[8:11].copy()
    )


def signed_distance(a, b, *, tolerance: float | None = None) -> float:
    """Signed distance between two convex hulls: gap > 0, minus the penetration depth < 0.

    Exactly 0.0 when the shapes touch within ``tolerance``. Parameters as :func:`query`.

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> round(signed_distance(cube, cube + [0.75, 0.0, 0.0]), 12)
    -0.25
    >>> signed_distance(cube, cube + [1.0, 0.0, 0.0])
    0.0
    """
    out = _run(a, b, tolerance, True)
    return 0.0 if out[0] == TOUCHING else float(out[1])


def intersects(a, b, *, tolerance: float | None = None) -> bool:
    """Whether two convex hulls meet: touching, penetrating, or undecided (conservatively).

    Parameters as :func:`query`; skips the penetration depth.

    Examples
    --------
    >>> import numpy as np
    >>> intersects([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1e-3]])
    False
    """
    out = _run(a, b, tolerance, False)
    return bool(out[0] != SEPARATED)


# ---------------------------------------------------------------------------------------------
# Batch
# ---------------------------------------------------------------------------------------------


# pack arrays, pairs, tolerances, max distances, depth?, then the five output arrays
_PAIRS = (F2D, I1D, I1D, I1D, F2D, F2D, I2D, F1D, F1D, B1, types.int8[::1], F1D, F2D, F2D, F2D)


def _PAIRS_SIG(*extra):
    return types.none(*_PAIRS, *extra)


@njit(_PAIRS_SIG(I8, I8), cache=True, nogil=True)
def _query_pairs_range(points, starts, nbr_starts, nbrs, lower, upper, pairs, tols, max_dists,
                       want_depth, status, distance, point_a, point_b, normal, q0, q1):  # fmt: skip
    """Answer pairs ``q0:q1`` (one task's share) into the output arrays."""
    W, SA, SB, box, centre, guess, lam, IX, _ = _workspace()
    fws, iws = epa_workspace()
    out = np.empty(11)
    for q in range(q0, q1):
        i, j = pairs[q, 0], pairs[q, 1]
        a0, a1, b0, b1 = starts[i], starts[i + 1], starts[j], starts[j + 1]
        climb_a = nbr_starts[a0 + 1] > nbr_starts[a0]
        climb_b = nbr_starts[b0 + 1] > nbr_starts[b0]
        for c in range(3):
            box[0, c], box[1, c] = lower[i, c], upper[i, c]
            box[2, c], box[3, c] = lower[j, c], upper[j, c]
        size, tol = _setup(box, tols[q], centre, guess)
        k = gjk(points, nbr_starts, nbrs, a0, a1, climb_a, points, nbr_starts, nbrs, b0, b1,
                climb_b, centre, guess, size, tol, max_dists[q], W, SA, SB, IX, lam,
                out)  # fmt: skip
        if k > 0:
            contact(points, nbr_starts, nbrs, a0, a1, climb_a, points, nbr_starts, nbrs, b0, b1,
                    climb_b, centre, size, tol, want_depth, k, W, SA, SB, IX, lam, fws, iws,
                    out)  # fmt: skip
        status[q] = np.int8(out[0])
        distance[q] = out[1]
        for c in range(3):
            point_a[q, c] = out[2 + c]
            point_b[q, c] = out[5 + c]
            normal[q, c] = out[8 + c]


# Compiled lazily (no signature): threads are opt-in, so nobody pays its ~4 s cold compile
# unless they use it. Its arguments always arrive as the types above.
@njit(cache=True, parallel=True)
def _query_pairs_parallel(points, starts, nbr_starts, nbrs, lower, upper, pairs, tols, max_dists,
                          want_depth, status, distance, point_a, point_b, normal,
                          chunks):  # fmt: skip
    """The pairs split into ``chunks`` contiguous shares, run as parallel tasks."""
    k = pairs.shape[0]
    for t in prange(chunks):
        _query_pairs_range(points, starts, nbr_starts, nbrs, lower, upper, pairs, tols,
                           max_dists, want_depth, status, distance, point_a, point_b, normal,
                           t * k // chunks, (t + 1) * k // chunks)  # fmt: skip


def _per_pair(value, k: int, name: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(k, default)
    arr = np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), (k,)))  # a fresh copy
    if np.isnan(arr).any() or (arr < 0.0).any():
        raise ValueError(f"{name} must be >= 0")
    return arr


def query_pairs(
    pack: ConvexPack,
    pairs: np.ndarray,
    *,
    tolerance: float | np.ndarray | None,
    depth: bool = True,
    max_distance: float | np.ndarray | None = None,
    threads: int = 1,
) -> PairQuery:
    """Relate many pairs of packed convex shapes in one compiled call.

    Parameters
    ----------
    pack : ConvexPack
        The shapes, from :func:`meshcheck.geometry.pack_convex` / ``concat_packs``.
    pairs : (k, 2) int64
        Shape indices into ``pack``; ``i < j`` by convention, any order works.
    tolerance : float or (k,) float64 or None, keyword-only
        Touching tolerance, absolute, model units. None: the default of :func:`query`, per pair.
    depth : bool, keyword-only
        If False, skip converging the penetration depth: a PENETRATING pair then gets
        ``distance = -L`` where ``0 < tol < L <= depth`` is a lower bound of its depth (the
        status is exact; the witness points and normal are those of the EPA face that gave L).
    max_distance : float or (k,) float64, optional, keyword-only
        Early exit: as soon as the distance is known to exceed ``max(max_distance, tolerance)``
        the pair is SEPARATED with ``distance`` set to that *lower bound* (not converged) and
        witness points of the current simplex. The pipeline passes clearance + tolerance, so
        every pair with ``distance <= max_distance`` is still measured exactly.
    threads : int, keyword-only
        Threads to spread the pairs over (numba ``prange``); 0 means numba's thread count
        (``NUMBA_NUM_THREADS``, by default the number of cores). Default 1: the calling thread
        only, because on the shared 2-core machine measured (``bench/gjk.py``) two threads
        ranged from 2.8x faster to 3x slower than one, depending on what else was running, and
        because numba's OpenMP thread layer makes a later ``fork()`` of the process unsafe (use
        the "spawn" start method).
        Fewer than ``PARALLEL_MIN_PAIRS`` pairs always run in the calling thread.

    Returns
    -------
    PairQuery
        One row per pair, in order.

    Examples
    --------
    >>> import numpy as np
    >>> from meshcheck.geometry import pack_convex
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> pack = pack_convex([cube, cube + [3.0, 0.0, 0.0], cube + [0.5, 0.0, 0.0]])
    >>> res = query_pairs(pack, np.array([[0, 1], [0, 2]]), tolerance=1e-9)
    >>> res.status.tolist(), np.round(res.distance, 12).tolist()
    ([0, 2], [2.0, -0.5])
    """
    pairs = _contiguous(pairs, np.int64)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"pairs: expected a (k, 2) array, got {pairs.shape}")
    k = pairs.shape[0]
    m = pack.starts.shape[0] - 1
    if k and (pairs.min() < 0 or pairs.max() >= m):
        raise ValueError(f"pairs: shape indices must be in [0, {m})")
    tols = _per_pair(tolerance, k, "tolerance", -1.0)
    max_dists = _per_pair(max_distance, k, "max_distance", np.inf)
    status = np.empty(k, dtype=np.int8)
    distance = np.empty(k)
    point_a = np.empty((k, 3))
    point_b = np.empty((k, 3))
    normal = np.empty((k, 3))
    if k:
        f8, i8 = np.float64, np.int64
        args = (
            _contiguous(pack.points, f8), _contiguous(pack.starts, i8),
            _contiguous(pack.nbr_starts, i8), _contiguous(pack.nbrs, i8),
            _contiguous(pack.lower, f8), _contiguous(pack.upper, f8),
            pairs, tols, max_dists, bool(depth), status, distance, point_a, point_b, normal,
        )  # fmt: skip
        threads = get_num_threads() if threads == 0 else max(1, int(threads))
        if threads > 1 and k >= PARALLEL_MIN_PAIRS:
            _query_pairs_parallel(*args, 4 * threads)
        else:
            _query_pairs_range(*args, 0, k)
    return PairQuery(status, distance, point_a, point_b, normal)
