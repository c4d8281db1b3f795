"""Exact triangle-triangle distance, the triangle pairs of two meshes within reach, and the
inscribed ball of a closed mesh: pure numba kernels for the verify stage.

Every function takes vertices ``(n, 3) float64`` and faces ``(m, 3) int64`` in a frame the caller
has re-centred near the region of interest, so coordinates far from the origin keep their digits.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_LEAF = 4  # triangles per BVH leaf
_STACK = 128  # BVH traversal stack; depth is about log2(m) for a median split


# ---------------------------------------------------------------------------------------------
# 3-vector helpers on tuples (no allocation in the inner loops)


@njit(cache=True, inline="always")
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, inline="always")
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, inline="always")
def _mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(cache=True, inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, inline="always")
def _vec(v, i):
    return (v[i, 0], v[i, 1], v[i, 2])


@njit(cache=True, inline="always")
def _clamp01(x):
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


# ---------------------------------------------------------------------------------------------
# Closest points between primitives (Ericson, Real-Time Collision Detection, 5.1.5 and 5.1.9)


@njit(cache=True)
def closest_point_triangle(p, a, b, c):
    """Closest point to ``p`` on triangle ``abc`` (3-tuples); a degenerate triangle gives ``a``
    and ``False`` so the caller can rely on the edge-edge distances instead."""
    ab = _sub(b, a)
    ac = _sub(c, a)
    n = _cross(ab, ac)
    if _dot(n, n) <= 1e-30 * (_dot(ab, ab) * _dot(ac, ac) + 1e-300):
        return a, False
    ap = _sub(p, a)
    d1 = _dot(ab, ap)
    d2 = _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a, True
    bp = _sub(p, b)
    d3 = _dot(ab, bp)
    d4 = _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b, True
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _add(a, _mul(ab, d1 / (d1 - d3))), True
    cp = _sub(p, c)
    d5 = _dot(ab, cp)
    d6 = _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c, True
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _add(a, _mul(ac, d2 / (d2 - d6))), True
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return _add(b, _mul(_sub(c, b), w)), True
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return _add(a, _add(_mul(ab, v), _mul(ac, w))), True


@njit(cache=True)
def closest_points_segments(p1, q1, p2, q2):
    """Closest points between segments ``p1q1`` and ``p2q2`` (3-tuples)."""
    d1 = _sub(q1, p1)
    d2 = _sub(q2, p2)
    r = _sub(p1, p2)
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    f = _dot(d2, r)
    tiny = 1e-300
    if a <= tiny and e <= tiny:
        return p1, p2
    if a <= tiny:
        s = 0.0
        t = _clamp01(f / e)
    else:
        c = _dot(d1, r)
        if e <= tiny:
            t = 0.0
            s = _clamp01(-c / a)
        else:
            b = _dot(d1, d2)
            denom = a * e - b * b
            s = _clamp01((b * f - c * e) / denom) if denom > 1e-14 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = _clamp01(-c / a)
            elif t > 1.0:
                t = 1.0
                s = _clamp01((b - c) / a)
    return _add(p1, _mul(d1, s)), _add(p2, _mul(d2, t))


@njit(cache=True)
def _segment_crosses(p, q, a, b, c):
    """Point where segment ``pq`` passes strictly through the interior of triangle ``abc``.

    Returns ``(True, point)``, or ``(False, p)`` when it does not, or only grazes an edge, a vertex
    or the plane (those contacts are found by the vertex-triangle and edge-edge distances).
    """
    n = _cross(_sub(b, a), _sub(c, a))
    sp = _dot(n, _sub(p, a))
    sq = _dot(n, _sub(q, a))
    if not ((sp > 0.0 and sq < 0.0) or (sp < 0.0 and sq > 0.0)):
        return False, p
    x = _add(p, _mul(_sub(q, p), sp / (sp - sq)))
    c1 = _dot(_cross(_sub(b, a), _sub(x, a)), n)
    c2 = _dot(_cross(_sub(c, b), _sub(x, b)), n)
    c3 = _dot(_cross(_sub(a, c), _sub(x, c)), n)
    if c1 > 0.0 and c2 > 0.0 and c3 > 0.0:
        return True, x
    return False, p


@njit(cache=True)
def triangle_distance(a0, a1, a2, b0, b1, b2):
    """Exact distance between two triangles (3-tuples of 3-tuples), with witness points.

    Returns
    -------
    distance : float
        0 when the triangles meet.
    point_a, point_b : 3-tuples
        Closest points on each triangle (the same point when an edge crosses the other triangle).
    crossing : bool
        True when an edge of one passes strictly through the interior of the other.
    """
    ta = (a0, a1, a2)
    tb = (b0, b1, b2)
    for i in range(3):
        hit, x = _segment_crosses(ta[i], ta[(i + 1) % 3], b0, b1, b2)
        if hit:
            return 0.0, x, x, True
        hit, x = _segment_crosses(tb[i], tb[(i + 1) % 3], a0, a1, a2)
        if hit:
            return 0.0, x, x, True
    best = np.inf
    pa = a0
    pb = b0
    for i in range(3):
        q, ok = closest_point_triangle(ta[i], b0, b1, b2)
        if ok:
            d = _sub(ta[i], q)
            dd = _dot(d, d)
            if dd < best:
                best, pa, pb = dd, ta[i], q
        q, ok = closest_point_triangle(tb[i], a0, a1, a2)
        if ok:
            d = _sub(tb[i], q)
            dd = _dot(d, d)
            if dd < best:
                best, pa, pb = dd, q, tb[i]
    for i in range(3):
        for j in range(3):
            x, y = closest_points_segments(ta[i], ta[(i + 1) % 3], tb[j], tb[(j + 1) % 3])
            d = _sub(x, y)
            dd = _dot(d, d)
            if dd < best:
                best, pa, pb = dd, x, y
    return np.sqrt(best), pa, pb, False


@njit(cache=True)
def _tri(v, f, k):
    return _vec(v, f[k, 0]), _vec(v, f[k, 1]), _vec(v, f[k, 2])


@njit(cache=True)
def _crossing_strength(a0, a1, a2, b0, b1, b2):
    """How far two crossing triangles pass through each other: the least of the four reaches of
    one triangle beyond the other's plane, on either side. Near 0 for faces resting on faces."""
    out = np.inf
    for s in range(2):
        if s == 0:
            p0, p1, p2, q0, q1, q2 = a0, a1, a2, b0, b1, b2
        else:
            p0, p1, p2, q0, q1, q2 = b0, b1, b2, a0, a1, a2
        n = _cross(_sub(q1, q0), _sub(q2, q0))
        ln = np.sqrt(_dot(n, n))
        if ln == 0.0:
            return 0.0
        h0 = _dot(n, _sub(p0, q0)) / ln
        h1 = _dot(n, _sub(p1, q0)) / ln
        h2 = _dot(n, _sub(p2, q0)) / ln
        out = min(out, max(h0, h1, h2), -min(h0, h1, h2))
    return out


# ---------------------------------------------------------------------------------------------
# Triangle pairs of two meshes within reach: a BVH over one mesh, queried with the other


@njit(cache=True)
def triangle_boxes(v, f):
    """Axis-aligned boxes of triangles: ``lower, upper`` each ``(m, 3) float64``."""
    m = f.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    for k in range(m):
        for d in range(3):
            x0 = v[f[k, 0], d]
            x1 = v[f[k, 1], d]
            x2 = v[f[k, 2], d]
            lo[k, d] = min(x0, x1, x2)
            hi[k, d] = max(x0, x1, x2)
    return lo, hi


@njit(cache=True)
def build_bvh(lo, hi):
    """Median-split BVH over boxes ``lo, hi (m, 3)``.

    Returns ``node_lo, node_hi (n, 3)``, ``child (n,)`` (first child index, -1 for a leaf; the
    second child is ``child + 1``), ``start, count (n,)`` (a leaf's range in ``order``) and
    ``order (m,)`` (box indices in leaf order).
    """
    m = lo.shape[0]
    cap = max(2 * m, 1)
    node_lo = np.empty((cap, 3))
    node_hi = np.empty((cap, 3))
    child = np.empty(cap, dtype=np.int64)
    start = np.empty(cap, dtype=np.int64)
    count = np.empty(cap, dtype=np.int64)
    for k in range(cap):
        child[k], start[k], count[k] = -1, 0, 0
    order = np.empty(m, dtype=np.int64)
    for k in range(m):
        order[k] = k
    # Loops rather than array expressions throughout: the same arithmetic, a shorter compile.
    cent = np.empty((m, 3))
    for k in range(m):
        for d in range(3):
            cent[k, d] = 0.5 * (lo[k, d] + hi[k, d])
    clo = np.empty(3)
    chi = np.empty(3)
    stack = np.empty((cap, 3), dtype=np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2] = 0, 0, m
    top = 1
    n_nodes = 1
    while top > 0:
        top -= 1
        node, s, e = stack[top, 0], stack[top, 1], stack[top, 2]
        for d in range(3):
            clo[d] = np.inf
            chi[d] = -np.inf
        for d in range(3):
            node_lo[node, d] = np.inf
            node_hi[node, d] = -np.inf
        for t in range(s, e):
            k = order[t]
            for d in range(3):
                node_lo[node, d] = min(node_lo[node, d], lo[k, d])
                node_hi[node, d] = max(node_hi[node, d], hi[k, d])
                clo[d] = min(clo[d], cent[k, d])
                chi[d] = max(chi[d], cent[k, d])
        if e - s <= _LEAF:
            start[node] = s
            count[node] = e - s
            continue
        axis = 0  # the first axis of largest centroid spread, as np.argmax picks it
        for d in range(1, 3):
            if chi[d] - clo[d] > chi[axis] - clo[axis]:
                axis = d
        idx = np.empty(e - s, dtype=np.int64)
        keys = np.empty(e - s)
        for t in range(e - s):
            idx[t] = order[s + t]
            keys[t] = cent[idx[t], axis]
        perm = np.argsort(keys)
        for t in range(e - s):
            order[s + t] = idx[perm[t]]
        mid = (s + e) // 2
        child[node] = n_nodes
        stack[top, 0], stack[top, 1], stack[top, 2] = n_nodes, s, mid
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = n_nodes + 1, mid, e
        top += 2
        n_nodes += 2
    return (
        node_lo[:n_nodes],
        node_hi[:n_nodes],
        child[:n_nodes],
        start[:n_nodes],
        count[:n_nodes],
        order,
    )


@njit(cache=True)
def _boxes_near(alo, ahi, blo, bhi, reach):
    for d in range(3):
        if alo[d] > bhi[d] + reach or blo[d] > ahi[d] + reach:
            return False
    return True


@njit(cache=True)
def box_pairs(alo, ahi, blo, bhi, reach):
    """Pairs ``(i, j)`` of boxes of two sets whose gap is at most ``reach`` along every axis.

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
    out = np.empty((max(16, 4 * (alo.shape[0] + blo.shape[0])), 2), dtype=np.int64)
    k = 0
    if alo.shape[0] == 0 or blo.shape[0] == 0:
        return out[:0]
    node_lo, node_hi, child, start, count, order = build_bvh(blo, bhi)
    stack = np.empty(_STACK, dtype=np.int64)
    for i in range(alo.shape[0]):
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if not _boxes_near(alo[i], ahi[i], node_lo[node], node_hi[node], reach):
                continue
            if child[node] < 0:
                for t in range(start[node], start[node] + count[node]):
                    j = order[t]
                    if _boxes_near(alo[i], ahi[i], blo[j], bhi[j], reach):
                        if k == out.shape[0]:
                            grown = np.empty((2 * k, 2), dtype=np.int64)
                            grown[:k] = out
                            out = grown
                        out[k, 0] = i
                        out[k, 1] = j
                        k += 1
            else:
                stack[top] = child[node]
                stack[top + 1] = child[node] + 1
                top += 2
    return out[:k]


@njit(cache=True)
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
        through each other (see ``_crossing_strength``); 0 for pairs that do not cross.
    """
    k = pairs.shape[0]
    dist = np.empty(k)
    pa = np.empty((k, 3))
    pb = np.empty((k, 3))
    strength = np.zeros(k)
    for t in range(k):
        a0, a1, a2 = _tri(va, fa, pairs[t, 0])
        b0, b1, b2 = _tri(vb, fb, pairs[t, 1])
        d, x, y, crossing = triangle_distance(a0, a1, a2, b0, b1, b2)
        dist[t] = d
        for c in range(3):
            pa[t, c] = x[c]
            pb[t, c] = y[c]
        if crossing:
            strength[t] = _crossing_strength(a0, a1, a2, b0, b1, b2)
    return dist, pa, pb, strength


# ---------------------------------------------------------------------------------------------
# Points against a whole mesh


@njit(cache=True)
def winding_numbers(points, v, f):
    """Generalized winding number of each point (1 inside a closed outward mesh, 0 outside).

    Van Oosterom and Strackee's solid angle of each triangle, summed over ``4 pi``.
    """
    out = np.zeros(points.shape[0])
    for i in range(points.shape[0]):
        p = _vec(points, i)
        total = 0.0
        for k in range(f.shape[0]):
            a = _sub(_vec(v, f[k, 0]), p)
            b = _sub(_vec(v, f[k, 1]), p)
            c = _sub(_vec(v, f[k, 2]), p)
            la = np.sqrt(_dot(a, a))
            lb = np.sqrt(_dot(b, b))
            lc = np.sqrt(_dot(c, c))
            num = _dot(a, _cross(b, c))
            den = la * lb * lc + _dot(a, b) * lc + _dot(a, c) * lb + _dot(b, c) * la
            total += 2.0 * np.arctan2(num, den)
        out[i] = total / (4.0 * np.pi)
    return out


@njit(cache=True)
def _point_mesh_distance(p, v, f):
    best = np.inf
    for k in range(f.shape[0]):
        a, b, c = _tri(v, f, k)
        q, ok = closest_point_triangle(p, a, b, c)
        if not ok:
            for e in range(3):
                _, q = closest_points_segments(p, p, (a, b, c)[e], (a, b, c)[(e + 1) % 3])
                d = _sub(p, q)
                best = min(best, _dot(d, d))
            continue
        d = _sub(p, q)
        best = min(best, _dot(d, d))
    return np.sqrt(best)


@njit(cache=True)
def point_distances(points, v, f):
    """Unsigned distance from each point ``(k, 3)`` to the nearest triangle of ``(v, f)``."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        out[i] = _point_mesh_distance(_vec(points, i), v, f)
    return out


@njit(cache=True)
def _ray_first_hit(o, d, v, f, skip):
    """Smallest ``t > 0`` where the ray ``o + t d`` meets a triangle other than ``skip``."""
    best = np.inf
    for k in range(f.shape[0]):
        if k == skip:
            continue
        a, b, c = _tri(v, f, k)
        e1 = _sub(b, a)
        e2 = _sub(c, a)
        h = _cross(d, e2)
        det = _dot(e1, h)
        if det == 0.0:
            continue
        inv = 1.0 / det
        s = _sub(o, a)
        u = _dot(s, h) * inv
        if u < 0.0 or u > 1.0:
            continue
        q = _cross(s, e1)
        w = _dot(d, q) * inv
        if w < 0.0 or u + w > 1.0:
            continue
        t = _dot(e2, q) * inv
        if 0.0 < t < best:
            best = t
    return best


@njit(cache=True)
def inscribed_ball(v, f, max_seeds):
    """Largest ball inside a closed, outward-wound mesh: ``(radius, centre 3-tuple)``.

    Seeds: from the centroid of (up to ``max_seeds``, evenly strided) faces, a ray along the inward
    normal to the first surface it meets; its midpoint is inside the solid, on the medial surface
    of any slab or shell. The best seeds are refined by a compass search over 26 directions whose
    step never exceeds the current radius, so every accepted point stays inside the solid.
    """
    m = f.shape[0]
    if m == 0:
        return 0.0, (0.0, 0.0, 0.0)
    stride = max(1, m // max_seeds)
    n_seeds = (m + stride - 1) // stride
    centres = np.zeros((n_seeds, 3))
    radii = np.zeros(n_seeds)
    for s in range(n_seeds):
        k = s * stride
        a, b, c = _tri(v, f, k)
        n = _cross(_sub(b, a), _sub(c, a))
        ln = np.sqrt(_dot(n, n))
        if ln == 0.0:
            continue
        inward = _mul(n, -1.0 / ln)
        o = _mul(_add(a, _add(b, c)), 1.0 / 3.0)
        t = _ray_first_hit(o, inward, v, f, k)
        if not np.isfinite(t):
            continue
        x = _add(o, _mul(inward, 0.5 * t))
        centres[s, 0], centres[s, 1], centres[s, 2] = x
        radii[s] = _point_mesh_distance(x, v, f)
    # 26 unit directions of the 3x3x3 neighbourhood.
    dirs = np.empty((26, 3))
    nd = 0
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            for k in (-1, 0, 1):
                if i == 0 and j == 0 and k == 0:
                    continue
                ln = np.sqrt(i * i + j * j + k * k)
                dirs[nd, 0], dirs[nd, 1], dirs[nd, 2] = i / ln, j / ln, k / ln
                nd += 1
    best_r = 0.0
    best_x = (0.0, 0.0, 0.0)
    order = np.argsort(-radii)
    for rank in range(min(8, n_seeds)):
        s = order[rank]
        r = radii[s]
        if r <= 0.0:
            break
        x = _vec(centres, s)
        step = 0.5 * r
        for _ in range(200):
            if step <= 1e-6 * r:
                break
            moved = False
            for di in range(26):
                y = _add(x, _mul(_vec(dirs, di), step))
                ry = _point_mesh_distance(y, v, f)
                if ry > r:
                    x, r, moved = y, ry, True
                    break
            if not moved:
                step *= 0.5
            else:
                step = min(2.0 * step, 0.9 * r)
        if r > best_r:
            best_r, best_x = r, x
    return best_r, best_x


@njit(cache=True)
def closest_points_on_triangles(p, v, f):
    """Distance from point ``p (3,)`` to every triangle, and the closest points ``(m, 3)``."""
    m = f.shape[0]
    dist = np.empty(m)
    q = np.empty((m, 3))
    x = (p[0], p[1], p[2])
    for k in range(m):
        a, b, c = _tri(v, f, k)
        y, ok = closest_point_triangle(x, a, b, c)
        if not ok:
            best = np.inf
            for e in range(3):
                _, z = closest_points_segments(x, x, (a, b, c)[e], (a, b, c)[(e + 1) % 3])
                d = _sub(x, z)
                if _dot(d, d) < best:
                    best, y = _dot(d, d), z
        d = _sub(x, y)
        dist[k] = np.sqrt(_dot(d, d))
        q[k, 0], q[k, 1], q[k, 2] = y
    return dist, q
