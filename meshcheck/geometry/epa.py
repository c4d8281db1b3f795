"""Penetration depth and normal: the Expanding Polytope Algorithm (EPA), and its entry from GJK.

GJK hands over when the origin lies on or inside its simplex, i.e. the shapes meet. This module
then

1. grows the simplex into a tetrahedron that holds the origin ("blow-up", as libccd's
   ``simplexToTetrahedron``), checking on the way whether the Minkowski difference ``D = A - B``
   is flat within the tolerance in some direction: then the shapes only touch;
2. expands the polytope towards the boundary of ``D`` (EPA). Each polytope lies inside ``D``, so
   its nearest face gives a *lower* bound on the depth; every support value ``h_D(n)`` gives an
   *upper* bound. It stops on their gap, like GJK on the distance bounds.

All compiled functions work in re-centred coordinates and write their answer into the ``out``
array described in :func:`write_answer`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

from .constants import (
    DEGENERATE_SIN,
    EPA_MAX_ITER,
    EPA_REL_GAP,
    PENETRATING,
    TOUCHING,
    UNDECIDED,
    ZERO_REL,
)
from .support import B1, F1D, F2D, F8, I1D, I2D, I8, SHAPE, cso_support

#: Work-array sizes: the polytope gains one vertex per iteration (plus the 4-5 it starts with);
#: a closed triangulated polytope has at most ``2 V - 4`` faces.
_MAX_VERTS = EPA_MAX_ITER + 8
_MAX_FACES = 2 * _MAX_VERTS

_GJK_SIMPLEX = (I8, F2D, F2D, F2D, I2D, F1D)  # k, W, SA, SB, IX, lam
_CONTACT_SIG = types.none(*SHAPE, *SHAPE, F1D, F8, F8, B1, *_GJK_SIMPLEX, F2D, I1D, F1D)
_EPA_SIG = types.none(
    *SHAPE, *SHAPE, F1D, F8, F8, B1, F2D, F2D, F2D, I2D, I2D, F2D, F1D, I1D, I1D, I2D, F1D
)


@njit(types.none(F1D, I8, F8, F8, F8, F8, F8, F8, F8, F8, F8, F8, F1D), cache=True, nogil=True)
def write_answer(out, status, distance, ax, ay, az, bx, by, bz, nx, ny, nz, centre):
    """Store one answer, moving the witness points back to world coordinates.

    ``out`` is (11,) float64: ``[status, distance, point_a(3), point_b(3), normal(3)]``. A normal
    that cannot be normalised (zero length) is replaced by +x so nothing is ever NaN.
    """
    nn = np.sqrt(nx * nx + ny * ny + nz * nz)
    if nn > 0.0 and np.isfinite(nn):
        nx, ny, nz = nx / nn, ny / nn, nz / nn
    else:
        nx, ny, nz = 1.0, 0.0, 0.0
    if not np.isfinite(distance):
        distance = 0.0
    out[0] = status
    out[1] = distance + 0.0  # + 0.0 turns -0.0 into 0.0
    out[2] = ax + centre[0]
    out[3] = ay + centre[1]
    out[4] = az + centre[2]
    out[5] = bx + centre[0]
    out[6] = by + centre[1]
    out[7] = bz + centre[2]
    out[8] = nx + 0.0
    out[9] = ny + 0.0
    out[10] = nz + 0.0


@njit(F8(F8), cache=True, nogil=True)
def _neg(x):
    """``-x`` for ``x > 0``, else 0.0 (never -0.0): a depth bound as a signed distance."""
    return -x if x > 0.0 else 0.0


@njit(types.UniTuple(F8, 2)(F2D, I8, I8), cache=True, nogil=True)
def closest_on_segment(W, i, j):
    """Barycentric weights ``(l_i, l_j)`` of the point of segment ``W[i] W[j]`` nearest 0."""
    ax, ay, az = W[i, 0], W[i, 1], W[i, 2]
    ex, ey, ez = W[j, 0] - ax, W[j, 1] - ay, W[j, 2] - az
    den = ex * ex + ey * ey + ez * ez
    if den <= 0.0:
        return 0.0, 1.0
    t = -(ax * ex + ay * ey + az * ez) / den
    if t <= 0.0:
        return 1.0, 0.0
    if t >= 1.0:
        return 0.0, 1.0
    return 1.0 - t, t


@njit(types.UniTuple(F8, 3)(F2D, I8, I8, I8), cache=True, nogil=True)
def closest_on_triangle(W, i, j, k):
    """Weights ``(l_i, l_j, l_k)`` of the point of triangle ``W[i] W[j] W[k]`` nearest the origin.

    Voronoi-region tests of Ericson (Real-Time Collision Detection, 5.1.5). A needle or
    zero-area triangle (sine of its corner below ``DEGENERATE_SIN``) is answered by its best edge.
    """
    ax, ay, az = W[i, 0], W[i, 1], W[i, 2]
    bx, by, bz = W[j, 0], W[j, 1], W[j, 2]
    cx, cy, cz = W[k, 0], W[k, 1], W[k, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    ab2 = abx * abx + aby * aby + abz * abz
    ac2 = acx * acx + acy * acy + acz * acz
    bc2 = (cx - bx) ** 2 + (cy - by) ** 2 + (cz - bz) ** 2
    n2 = nx * nx + ny * ny + nz * nz
    if n2 <= DEGENERATE_SIN * DEGENERATE_SIN * ab2 * ac2 or bc2 <= 0.0:
        # Degenerate: the nearest point is on one of the edges.
        best = np.inf
        li = lj = lk = 0.0
        s, t = closest_on_segment(W, i, j)
        px, py, pz = s * ax + t * bx, s * ay + t * by, s * az + t * bz
        d = px * px + py * py + pz * pz
        if d < best:
            best, li, lj, lk = d, s, t, 0.0
        s, t = closest_on_segment(W, i, k)
        px, py, pz = s * ax + t * cx, s * ay + t * cy, s * az + t * cz
        d = px * px + py * py + pz * pz
        if d < best:
            best, li, lj, lk = d, s, 0.0, t
        s, t = closest_on_segment(W, j, k)
        px, py, pz = s * bx + t * cx, s * by + t * cy, s * bz + t * cz
        d = px * px + py * py + pz * pz
        if d < best:
            best, li, lj, lk = d, 0.0, s, t
        return li, lj, lk
    d1 = -(abx * ax + aby * ay + abz * az)
    d2 = -(acx * ax + acy * ay + acz * az)
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    d3 = -(abx * bx + aby * by + abz * bz)
    d4 = -(acx * bx + acy * by + acz * bz)
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return 1.0 - t, t, 0.0
    d5 = -(abx * cx + aby * cy + abz * cz)
    d6 = -(acx * cx + acy * cy + acz * cz)
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return 1.0 - t, 0.0, t
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - t, t
    denom = va + vb + vc
    v = vb / denom
    w = vc / denom
    return 1.0 - v - w, v, w


@njit(types.none(F2D, I2D, F2D, F1D, I8, I8, I8, I8), cache=True, nogil=True)
def _set_face(V, FV, FN, FD, f, i, j, k):
    """Store face ``f = (i, j, k)`` with its unit normal and plane offset (inf if degenerate)."""
    FV[f, 0], FV[f, 1], FV[f, 2] = i, j, k
    abx, aby, abz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
    acx, acy, acz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
    nx = aby * acz - abz * acy
    ny = abz * acx - abx * acz
    nz = abx * acy - aby * acx
    nn = np.sqrt(nx * nx + ny * ny + nz * nz)
    scale = np.sqrt((abx * abx + aby * aby + abz * abz) * (acx * acx + acy * acy + acz * acz))
    if nn <= DEGENERATE_SIN * scale or nn == 0.0:
        FN[f, 0] = FN[f, 1] = FN[f, 2] = 0.0
        FD[f] = np.inf
        return
    FN[f, 0], FN[f, 1], FN[f, 2] = nx / nn, ny / nn, nz / nn
    FD[f] = (nx * V[i, 0] + ny * V[i, 1] + nz * V[i, 2]) / nn


@njit(types.none(I8, F8, I8, F2D, F2D, F2D, I2D, F2D, F8, F8, F8, F1D, F1D), cache=True, nogil=True)
def _answer_face(status, distance, f, V, VA, VB, FV, FN, nx, ny, nz, centre, out):
    """Answer with the witness points of the point of face ``f`` nearest the origin."""
    i, j, k = FV[f, 0], FV[f, 1], FV[f, 2]
    li, lj, lk = closest_on_triangle(V, i, j, k)
    write_answer(
        out,
        status,
        distance,
        li * VA[i, 0] + lj * VA[j, 0] + lk * VA[k, 0],
        li * VA[i, 1] + lj * VA[j, 1] + lk * VA[k, 1],
        li * VA[i, 2] + lj * VA[j, 2] + lk * VA[k, 2],
        li * VB[i, 0] + lj * VB[j, 0] + lk * VB[k, 0],
        li * VB[i, 1] + lj * VB[j, 1] + lk * VB[k, 1],
        li * VB[i, 2] + lj * VB[j, 2] + lk * VB[k, 2],
        nx,
        ny,
        nz,
        centre,
    )


@njit(types.none(F2D, F2D, F2D, I2D, I8, I8), cache=True, nogil=True)
def _copy_row(V, VA, VB, VI, src, dst):
    for c in range(3):
        V[dst, c] = V[src, c]
        VA[dst, c] = VA[src, c]
        VB[dst, c] = VB[src, c]
    VI[dst, 0] = VI[src, 0]
    VI[dst, 1] = VI[src, 1]


# The two shapes as flat arguments (see :func:`meshcheck.geometry.support.cso_support`), in
# every signature below: ``pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, ..., climb_b``.


@njit(F8(*SHAPE, *SHAPE, F1D, F8, F8, F8, F2D, F2D, F2D, I2D, I8), cache=True, nogil=True)
def _support_into(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b,
                  centre, dx, dy, dz, V, VA, VB, VI, slot):  # fmt: skip
    """Put the support point of ``A - B`` along ``d`` into row ``slot``; return its ``. d``."""
    ia, ib = cso_support(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1,
                         climb_b, centre, dx, dy, dz, VI[0, 0], VI[0, 1])  # fmt: skip
    for c in range(3):
        VA[slot, c] = pts_a[ia, c] - centre[c]
        VB[slot, c] = pts_b[ib, c] - centre[c]
        V[slot, c] = VA[slot, c] - VB[slot, c]
    VI[slot, 0] = ia
    VI[slot, 1] = ib
    return V[slot, 0] * dx + V[slot, 1] * dy + V[slot, 2] * dz


@njit(types.Tuple((F2D, I1D))(), cache=True, nogil=True)
def epa_workspace():
    """Work arrays for :func:`contact`: ``(floats, ints)``, allocated once per batch."""
    floats = np.empty((3 * _MAX_VERTS + _MAX_FACES + _MAX_FACES // 3 + 1, 3))
    ints = np.empty(2 * _MAX_VERTS + 3 * _MAX_FACES + 2 * _MAX_FACES + 6 * _MAX_FACES, np.int64)
    return floats, ints


_VIEWS = types.Tuple((F2D, F2D, F2D, I2D, I2D, F2D, F1D, I1D, I1D, I2D))


@njit(_VIEWS(F2D, I1D), cache=True, nogil=True)
def _carve(floats, ints):
    """Views into the work arrays: polytope vertices, their sources and the faces."""
    mv, mf = _MAX_VERTS, _MAX_FACES
    V, VA, VB = floats[0:mv], floats[mv : 2 * mv], floats[2 * mv : 3 * mv]
    FN = floats[3 * mv : 3 * mv + mf]
    FD = floats[3 * mv + mf :].reshape(-1)[:mf]
    VI = ints[0 : 2 * mv].reshape((mv, 2))
    o = 2 * mv
    FV = ints[o : o + 3 * mf].reshape((mf, 3))
    o += 3 * mf
    alive, free = ints[o : o + mf], ints[o + mf : o + 2 * mf]
    o += 2 * mf
    edges = ints[o : o + 6 * mf].reshape((3 * mf, 2))
    return V, VA, VB, VI, FV, FN, FD, alive, free, edges


@njit(_EPA_SIG, cache=True, nogil=True)
def epa(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b,
        centre, size, tol, want_depth, V, VA, VB, VI, FV, FN, FD, alive, free, edges,
        out):  # fmt: skip
    """Expand the tetrahedron ``V[:4]`` (holding the origin) to the depth of ``A - B``.

    Parameters are those of :func:`contact`; ``V, VA, VB, VI`` hold the start tetrahedron in
    their first four rows, the face arrays are work space (see :func:`_carve`).

    The depth is bracketed by ``lower`` (nearest face of the polytope, which lies inside ``D``)
    and ``upper`` (least support value ``h_D(n)`` seen). The answer is

    * TOUCHING when ``upper <= tol``;
    * PENETRATING when ``lower > tol`` (at once if not ``want_depth``, with ``-lower``);
    * else the converged depth decides; on the iteration cap without a decision, UNDECIDED.
    """
    zero_len = min(ZERO_REL * size, 0.5 * tol)
    nv = 4

    # Start faces, turned so their normals point away from the centroid (an interior point).
    gx = 0.25 * (V[0, 0] + V[1, 0] + V[2, 0] + V[3, 0])
    gy = 0.25 * (V[0, 1] + V[1, 1] + V[2, 1] + V[3, 1])
    gz = 0.25 * (V[0, 2] + V[1, 2] + V[2, 2] + V[3, 2])
    for f in range(4):
        if f == 0:
            i, j, k = 0, 1, 2
        elif f == 1:
            i, j, k = 0, 3, 1
        elif f == 2:
            i, j, k = 0, 2, 3
        else:
            i, j, k = 1, 3, 2
        ox, oy, oz = gx - V[i, 0], gy - V[i, 1], gz - V[i, 2]
        abx, aby, abz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
        acx, acy, acz = V[k, 0] - V[i, 0], V[k, 1] - V[i, 1], V[k, 2] - V[i, 2]
        side = (
            ox * (aby * acz - abz * acy)
            + oy * (abz * acx - abx * acz)
            + oz * (abx * acy - aby * acx)
        )
        if side > 0.0:
            j, k = k, j
        _set_face(V, FV, FN, FD, f, i, j, k)
        alive[f] = 1
    nf = 4
    nfree = 0

    lower = -np.inf
    upper = np.inf
    ux, uy, uz = 1.0, 0.0, 0.0
    best = -1
    for _ in range(EPA_MAX_ITER):
        best = -1
        dmin = np.inf
        for f in range(nf):
            if alive[f] and FD[f] < dmin:
                dmin = FD[f]
                best = f
        if best < 0:
            break
        if dmin > lower:
            lower = dmin
        nx, ny, nz = FN[best, 0], FN[best, 1], FN[best, 2]
        if not want_depth and lower > tol:
            _answer_face(PENETRATING, -lower, best, V, VA, VB, FV, FN, nx, ny, nz, centre, out)
            return
        if nv >= _MAX_VERTS:
            break
        h = _support_into(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1,
                          climb_b, centre, nx, ny, nz, V, VA, VB, VI, nv)  # fmt: skip
        if h < upper:
            upper = h
            ux, uy, uz = nx, ny, nz
        if upper <= tol:
            _answer_face(TOUCHING, _neg(upper), best, V, VA, VB, FV, FN, ux, uy, uz, centre, out)
            return
        converged = h - dmin <= EPA_REL_GAP * abs(h) + zero_len
        if not converged:
            for r in range(nv):
                if VI[r, 0] == VI[nv, 0] and VI[r, 1] == VI[nv, 1]:
                    converged = True
                    break
        if converged:
            status = PENETRATING if dmin > tol else TOUCHING
            _answer_face(status, -dmin, best, V, VA, VB, FV, FN, nx, ny, nz, centre, out)
            return
        # Remove the faces the new point sees; their outline (the horizon) is kept as the
        # directed edges whose reverse is not also removed.
        wx, wy, wz = V[nv, 0], V[nv, 1], V[nv, 2]
        ne = 0
        for f in range(nf):
            if not alive[f]:
                continue
            if f != best and FN[f, 0] * wx + FN[f, 1] * wy + FN[f, 2] * wz - FD[f] <= zero_len:
                continue
            alive[f] = 0
            free[nfree] = f
            nfree += 1
            for e in range(3):
                p, q = FV[f, e], FV[f, (e + 1) % 3]
                found = -1
                for s in range(ne):
                    if edges[s, 0] == q and edges[s, 1] == p:
                        found = s
                        break
                if found >= 0:
                    ne -= 1
                    edges[found, 0] = edges[ne, 0]
                    edges[found, 1] = edges[ne, 1]
                else:
                    edges[ne, 0] = p
                    edges[ne, 1] = q
                    ne += 1
        for s in range(ne):
            if nfree > 0:
                nfree -= 1
                f = free[nfree]
            else:
                f = nf
                nf += 1
            _set_face(V, FV, FN, FD, f, edges[s, 0], edges[s, 1], nv)
            alive[f] = 1
        nv += 1

    # Iteration cap (or numerical trouble): decide from the bounds where they allow it.
    if best < 0:
        write_answer(out, UNDECIDED, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ux, uy, uz, centre)
    elif lower > tol:
        nx, ny, nz = FN[best, 0], FN[best, 1], FN[best, 2]
        _answer_face(PENETRATING, -lower, best, V, VA, VB, FV, FN, nx, ny, nz, centre, out)
    elif upper <= tol:
        _answer_face(TOUCHING, _neg(upper), best, V, VA, VB, FV, FN, ux, uy, uz, centre, out)
    else:
        _answer_face(UNDECIDED, _neg(lower), best, V, VA, VB, FV, FN, ux, uy, uz, centre, out)


@njit(_CONTACT_SIG, cache=True, nogil=True)
def contact(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b,
            centre, size, tol, want_depth, k, W, SA, SB, IX, lam, floats, ints, out):  # fmt: skip
    """Classify and measure a pair whose GJK simplex holds the origin (the shapes meet).

    Parameters
    ----------
    pts_a, ..., climb_b, centre
        The two shapes and the common centre, as for
        :func:`meshcheck.geometry.support.cso_support`.
    size : float64
        Size of the query (largest AABB edge), model units.
    tol : float64
        Touching tolerance, model units.
    want_depth : bool
        Converge the depth. If False, stop as soon as the status is known: a PENETRATING answer
        then carries minus a *lower bound* of the depth.
    k : int64
        Number of simplex points (1 to 4). With ``k < 4`` the origin lies on the simplex (within
        rounding or ``tol``); with ``k == 4`` the tetrahedron encloses it.
    W, SA, SB, IX, lam
        The GJK simplex: Minkowski points, their source points on A and B (re-centred), source
        indices, barycentric weights of the origin's nearest point.
    floats, ints
        Work arrays from :func:`epa_workspace`.
    out : (11,) float64
        Receives the answer (see :func:`write_answer`).
    """
    V, VA, VB, VI, FV, FN, FD, alive, free, edges = _carve(floats, ints)
    # Where GJK found the origin: the witness points of a touching answer.
    pax = pay = paz = pbx = pby = pbz = 0.0
    for r in range(k):
        pax += lam[r] * SA[r, 0]
        pay += lam[r] * SA[r, 1]
        paz += lam[r] * SA[r, 2]
        pbx += lam[r] * SB[r, 0]
        pby += lam[r] * SB[r, 1]
        pbz += lam[r] * SB[r, 2]
        for c in range(3):
            V[r, c] = W[r, c]
            VA[r, c] = SA[r, c]
            VB[r, c] = SB[r, c]
        VI[r, 0] = IX[r, 0]
        VI[r, 1] = IX[r, 1]
    nv = k
    zero_len = ZERO_REL * size

    # -- Blow the simplex up to a tetrahedron holding the origin. Before each new point, the
    #    support value along its direction says whether D is flat there within tol: then the
    #    origin is within tol of D's boundary and the shapes only touch.
    passes = 0
    while nv < 4:
        passes += 1
        if passes > 8:
            # Needle triangles again and again: no tetrahedron can be built.
            write_answer(out, UNDECIDED, 0.0, pax, pay, paz, pbx, pby, pbz, 1.0, 0.0, 0.0, centre)
            return
        if nv == 1:
            grown = False
            for axis in range(6):
                sign = 1.0 if axis < 3 else -1.0
                dx = sign if axis % 3 == 0 else 0.0
                dy = sign if axis % 3 == 1 else 0.0
                dz = sign if axis % 3 == 2 else 0.0
                h = _support_into(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0,
                                  b1, climb_b, centre, dx, dy, dz, V, VA, VB, VI, 1)  # fmt: skip
                if h <= tol:
                    write_answer(out, TOUCHING, 0.0, pax, pay, paz, pbx, pby, pbz,
                                 dx, dy, dz, centre)  # fmt: skip
                    return
                if h - (V[0, 0] * dx + V[0, 1] * dy + V[0, 2] * dz) > zero_len:
                    grown = True
                    break
            if not grown:
                write_answer(out, UNDECIDED, 0.0, pax, pay, paz, pbx, pby, pbz,
                             1.0, 0.0, 0.0, centre)  # fmt: skip
                return
            nv = 2
        elif nv == 2:
            ex, ey, ez = V[1, 0] - V[0, 0], V[1, 1] - V[0, 1], V[1, 2] - V[0, 2]
            el = np.sqrt(ex * ex + ey * ey + ez * ez)
            if el <= zero_len:
                nv = 1
                continue
            # Two directions square to the segment (cross it with its least-aligned axis, then
            # with that); keep the support point that stands furthest off the segment's line.
            ax, ay, az = abs(ex), abs(ey), abs(ez)
            if ax <= ay and ax <= az:
                ux, uy, uz = 0.0, ez, -ey
            elif ay <= az:
                ux, uy, uz = -ez, 0.0, ex
            else:
                ux, uy, uz = ey, -ex, 0.0
            ul = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux, uy, uz = ux / ul, uy / ul, uz / ul
            first_h = 0.0
            for turn in range(2):
                if turn == 1:
                    ux, uy, uz = (
                        (ey * uz - ez * uy) / el,
                        (ez * ux - ex * uz) / el,
                        (ex * uy - ey * ux) / el,
                    )
                h = _support_into(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0,
                                  b1, climb_b, centre, ux, uy, uz, V, VA, VB, VI,
                                  2 + turn)  # fmt: skip
                if h <= tol:
                    write_answer(out, TOUCHING, 0.0, pax, pay, paz, pbx, pby, pbz,
                                 ux, uy, uz, centre)  # fmt: skip
                    return
                if turn == 0:
                    first_h = h
                elif h > first_h:
                    _copy_row(V, VA, VB, VI, 3, 2)
            nv = 3
        else:
            abx, aby, abz = V[1, 0] - V[0, 0], V[1, 1] - V[0, 1], V[1, 2] - V[0, 2]
            acx, acy, acz = V[2, 0] - V[0, 0], V[2, 1] - V[0, 1], V[2, 2] - V[0, 2]
            nx = aby * acz - abz * acy
            ny = abz * acx - abx * acz
            nz = abx * acy - aby * acx
            nn = np.sqrt(nx * nx + ny * ny + nz * nz)
            ab = np.sqrt(abx * abx + aby * aby + abz * abz)
            ac = np.sqrt(acx * acx + acy * acy + acz * acz)
            if nn <= DEGENERATE_SIN * ab * ac or nn == 0.0:
                # Needle triangle: keep its longest edge (the origin lies on it) and redo.
                bc = np.sqrt(
                    (V[2, 0] - V[1, 0]) ** 2 + (V[2, 1] - V[1, 1]) ** 2 + (V[2, 2] - V[1, 2]) ** 2
                )
                drop = 2 if (ab >= ac and ab >= bc) else (1 if ac >= bc else 0)
                for r in range(drop, 2):
                    _copy_row(V, VA, VB, VI, r + 1, r)
                nv = 2
                continue
            nx, ny, nz = nx / nn, ny / nn, nz / nn
            for side in (-1.0, 1.0):  # the +n point stays in row 3
                h = _support_into(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0,
                                  b1, climb_b, centre, side * nx, side * ny, side * nz,
                                  V, VA, VB, VI, 3)  # fmt: skip
                if h <= tol:
                    write_answer(out, TOUCHING, 0.0, pax, pay, paz, pbx, pby, pbz,
                                 side * nx, side * ny, side * nz, centre)  # fmt: skip
                    return
            nv = 4
    epa(pts_a, nst_a, nbr_a, a0, a1, climb_a, pts_b, nst_b, nbr_b, b0, b1, climb_b,
        centre, size, tol, want_depth, V, VA, VB, VI, FV, FN, FD, alive, free, edges,
        out)  # fmt: skip
