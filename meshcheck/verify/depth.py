"""Depth of a closed solid: the diameter of the largest ball inside it, as a certified interval.

The distance from a point to the surface, ``d(x) = min_i dist(x, T_i)`` over the triangles
``T_i``, is the radius a ball centred at ``x`` can have. The depth is ``2 max d`` over the points
inside. This module brackets it, and the verify stage calls a shared solid touching only when
the *upper* end is within the tolerance: a ball that was not found proves nothing.

lower bound
    a ball it exhibits: a centre whose winding number says it is inside, at its exact distance
    to the surface. Candidates: the inscribed balls of the pieces' convex hulls (exact for a
    convex solid), ``inscribed_ball`` (inward rays from faces, compass search), midpoints of
    rays along the inward bisectors of bent edges (a thin wall's thickest spot is a corner
    ball, touching an edge, which face rays and ascents from a wall's flat middle never reach),
    and box centres of the search below; the best are grown by successive linear programs.
upper bound
    the least of three proofs, cheapest first:

    - per connected piece, half its box's smallest extent, the radius of a ball of its volume,
      and the inradius of its convex hull (read from the LP's dual, so the solver's tolerances
      cannot make it low);
    - a thinness certificate (only to decide touching): a ball of radius ``rho`` centred in a
      box lies in the solid's part within the box grown by ``rho`` (a manifold3d boolean), so
      in that part's hull; boxes are halved across the direction the surface bends until every
      hull is thinner than ``rho``. Curved slivers (a pin in a hole of its own size) pass this.
    - a branch and bound over boxes, with the 1-Lipschitz bound ``s(c) + h`` (signed distance
      at the centre, half-diagonal) and a convexity bound: ``dist(x, K)`` is convex for every
      flat convex polygon ``K`` of the surface, so ``d(x) <= sum_i w_i dist(x, K_i)`` for
      weights summing to 1, whose maximum over the box is at a corner (the best weights are an
      LP); exact on flat walls. It certifies convex and compact solids to 1e-3; on a thin shell
      it would need boxes as thin as the wall, so there it stops at its budget and the interval
      it reports is wide (the lower end is still a ball that fits).

Numpy and scipy, manifold3d for the certificate's booleans, and the verify kernels of
``geometry.triangles``; no I/O.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from ..geometry.constants import (
    ASCENT_REL,
    BOUND_SAFETY_REL,
    CONVEX_AREA_REL,
    COPLANAR_COS,
    COPLANAR_OFFSET_REL,
    DUAL_WEIGHT_MIN,
    FLAT_EDGE_COS,
    MIN_BISECTOR,
    RAY_SKIP_REL,
)
from ..geometry.lp import largest_ball
from ..geometry.triangles import (
    closest_points_on_triangles,
    inscribed_ball,
    point_distances,
    ray_hits,
    winding_numbers,
)
from ..mesh import manifold_solid

#: Relative gap between the bounds at which the search stops: the lower bound is then within
#: 1e-3 of the largest ball, which is the accuracy the depth is documented to have.
REL_GAP = 1e-3

#: Boxes the search may spend to prove a solid thinner than a tolerance, after the thinness
#: certificate failed: a thick non-convex solid whose largest ball sits just under it.
DECIDE_BOXES = 100

#: Boxes evaluated before the search gives up and reports the bounds it has, by default. Each
#: box costs a pass over the triangles (distance and winding number at its centre), exact
#: distances from its corners to the nearby polygons and a small LP: 5-10 ms in all, so 500
#: boxes are a few seconds; convex and compact solids finish in tens, thin shells never do.
MAX_BOXES = 500

#: Pieces cut by the thinness certificate (``_is_thinner_than``) before it gives up; each is
#: a manifold3d boolean and a hull, about a millisecond on a sliver of a few hundred triangles.
MAX_PIECES = 1024

#: Triangles near a box centre whose polygons enter the convexity bound.
_NEAREST = 10

#: Faces (and as many edges) cast inward to seed the ball; caps the cost on large solids.
_MAX_SEEDS = 1024

#: Edge seeds grown by the successive-LP ascent, of the reflex and of the convex edges each (the
#: best ones, at least a radius apart).
_ASCENTS = 2


@dataclass(frozen=True)
class DepthBounds:
    """The depth of a solid, bracketed.

    Attributes
    ----------
    lower : float
        Diameter of the ball ``centre``, ``radius``: inside the solid, so the depth is at least
        this. Model units; 0 when no ball was looked for (``upper`` decided first).
    upper : float
        The depth is at most this (a proof, see the module docstring). Model units.
    centre : (3,) float64 or None
        Centre of the certified ball, frame of the vertices.
    boxes : int
        Boxes the upper-bound search evaluated.
    """

    lower: float
    upper: float
    centre: np.ndarray | None = None
    boxes: int = 0

    @property
    def is_certified(self) -> bool:
        """True when ``lower`` is within ``REL_GAP`` of ``upper``."""
        return self.upper <= self.lower * (1.0 + REL_GAP) + 1e-300


def depth_bounds(
    v: np.ndarray,
    f: np.ndarray,
    *,
    decide_at: float | None = None,
    rel_gap: float = REL_GAP,
    max_boxes: int = MAX_BOXES,
) -> DepthBounds:
    """Bracket the diameter of the largest ball inside a closed solid.

    Parameters
    ----------
    v : (n, 3) float64
        Vertices, model units, re-centred near the solid.
    f : (m, 3) int64
        Faces of a closed, outward-wound mesh.
    decide_at : float, optional
        A threshold (the touching tolerance): stop as soon as the upper bound is at most this
        (the depth is then proven not to exceed it); the lower bound may be 0 in that case.
    rel_gap : float
        Stop when ``upper <= lower * (1 + rel_gap)``.
    max_boxes : int
        Upper-bound search budget; when spent the bounds reached are returned. With
        ``decide_at``, the search only runs when the ball found does not already exceed it.

    Returns
    -------
    DepthBounds

    Examples
    --------
    >>> import trimesh
    >>> slab = trimesh.creation.box(extents=[5, 4, 0.25])
    >>> b = depth_bounds(slab.vertices, slab.faces)
    >>> round(b.lower, 9), b.is_certified
    (0.25, True)
    """
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.int64)
    if len(f) == 0:
        return DepthBounds(0.0, 0.0)
    upper_radius, centres = _upper_radius(v, f)
    upper = 2.0 * upper_radius
    if decide_at is not None and upper <= decide_at:
        return DepthBounds(0.0, upper)
    search = _Search(v, f)
    for x in centres:  # the hull's inscribed ball is the answer for a convex solid
        search.offer(x)
    if search.radius * (1.0 + rel_gap) < upper_radius:
        search.seed()
    if decide_at is not None and search.radius * 2.0 > decide_at:
        # Interference is proven by the ball; the box search would only narrow the upper bound.
        max_boxes = 0
    elif decide_at is not None:
        if _is_thinner_than(v, f, 0.5 * decide_at, MAX_PIECES):
            # A curved sliver: no box search gets below its tolerance, its pieces' hulls do.
            return DepthBounds(2.0 * search.radius, decide_at, search.centre)
        max_boxes = min(max_boxes, DECIDE_BOXES)
    search.branch_and_bound(
        upper_radius=0.5 * upper,
        decide_at=None if decide_at is None else 0.5 * decide_at,
        rel_gap=rel_gap,
        max_boxes=max_boxes,
    )
    return DepthBounds(
        2.0 * search.radius,
        min(upper, 2.0 * search.upper_radius),
        search.centre,
        search.boxes,
    )


def _upper_radius(v: np.ndarray, f: np.ndarray) -> tuple[float, list[np.ndarray]]:
    """Cheap upper bound on the largest ball's radius: the largest over the solid's connected
    pieces of the least of three radii, each of a ball that could not fit otherwise: half the
    piece's smallest box extent, the radius of a ball of the piece's volume, and the inradius of
    the piece's convex hull (exact for a convex piece, such as two boxes' overlap). Also returns
    the centres of those hulls' inscribed balls, candidates for the lower bound."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(v)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    face_label = label[f[:, 0]]
    # The faces of each piece, in their order in ``f``: one stable sort instead of a pass over all
    # faces per piece (a shared solid can have thousands of pieces).
    order = np.argsort(face_label, kind="stable")
    starts = np.searchsorted(face_label[order], np.arange(count + 1))
    best = 0.0
    centres = []
    for piece in range(count):
        pf = f[order[starts[piece] : starts[piece + 1]]]
        if len(pf) == 0:
            continue
        pv = v[np.unique(pf)]
        extent = float((pv.max(axis=0) - pv.min(axis=0)).min())
        a, b, c = (v[pf[:, k]] - pv[0] for k in range(3))
        volume = max(float(np.einsum("ij,ij->", a, _cross(b, c))) / 6.0, 0.0)
        radius = min(0.5 * extent, (0.75 * volume / math.pi) ** (1.0 / 3.0))
        if radius > best:
            inradius, centre = _hull_inradius(pv)
            best = max(best, min(radius, inradius))
            if centre is not None:
                centres.append(centre)
    return best, centres


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of ``(k, 3)`` rows, the same operations (so the same bits) without its
    per-call overhead."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def _is_thinner_than(v: np.ndarray, f: np.ndarray, radius: float, max_pieces: int) -> bool:
    """Prove that no ball of ``radius`` fits in the solid (True), or fail to (False).

    A ball of radius ``radius`` centred in a box ``C`` lies in the piece of the solid inside
    ``C`` grown by ``radius``, hence in that piece's convex hull: when the hull's inradius is
    below ``radius`` for every box of a cover of the solid's box, there is no such ball. Boxes
    are halved across their longest edge until that holds (a thin curved shell becomes flat
    enough in small pieces) or they are no larger than the ball (then it may well fit).
    """
    import manifold3d

    if not radius > 0.0:
        return False
    solid = manifold_solid(v, f)
    if solid is None:
        return False
    stack = [(v.min(axis=0), v.max(axis=0))]
    pieces = 0
    while stack:
        lo, hi = stack.pop()
        pieces += 1
        if pieces > max_pieces:
            return False
        grown = manifold3d.Manifold.cube(hi - lo + 2.0 * radius).translate(lo - radius)
        cut = (solid ^ grown).to_mesh64()
        points = np.asarray(cut.vert_properties)[:, :3]
        if len(points) == 0:
            continue
        extent = float((points.max(axis=0) - points.min(axis=0)).min())
        if min(0.5 * extent, _hull_inradius(points)[0]) < radius:
            continue
        if (hi - lo).max() <= radius:
            return False
        # Halve across the axis along which the surface turns most (a shell bends along one
        # axis, not along its length): the area-weighted slope of the normals along each axis.
        axis = _bending_axis(cut, hi - lo)
        mid = 0.5 * (lo + hi)
        mid = mid[axis]
        left_hi, right_lo = hi.copy(), lo.copy()
        left_hi[axis], right_lo[axis] = mid, mid
        stack += [(lo, left_hi), (right_lo, hi)]
    return True


def _bending_axis(mesh, extent: np.ndarray) -> int:
    """The longest axis of ``extent`` across which a manifold3d mesh's surface bends: the axis
    of a cylindrical shell (the direction its normals never take) is the one not to cut."""
    v = np.asarray(mesh.vert_properties)[:, :3]
    t = v[np.asarray(mesh.tri_verts, dtype=np.int64)]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    area = np.linalg.norm(n, axis=1)
    if area.sum() <= 0.0:
        return int(np.argmax(extent))
    # Area-weighted tensor of the normals (sum of w n n^T = n^T n / |n|, trace 1).
    tensor = (n / np.maximum(area, 1e-300)[:, None]).T @ n / area.sum()
    straight = np.linalg.eigh(tensor)[1][:, 0]
    return int(np.argmax(extent * (1.0 - straight**2) + 1e-9 * extent))


def _hull_inradius(points: np.ndarray) -> tuple[float, np.ndarray | None]:
    """Upper bound on the inradius of the convex hull of ``points`` (``inf`` when unknown), and
    the centre the solver found (None when it failed).

    The Chebyshev-centre linear program is solved in coordinates scaled to the points' box
    (``geometry.lp.largest_ball``), and the bound is the one its dual multipliers prove (valid
    whatever the solver's tolerances), not the primal objective."""
    from scipy.spatial import ConvexHull, QhullError

    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    scale = float(np.abs(points - centre).max())
    if scale == 0.0:
        return 0.0, None
    unit = (points - centre) / scale
    try:
        eq = ConvexHull(unit).equations  # n . x + o <= 0 inside, |n| = 1
    except (QhullError, ValueError):
        return math.inf, None
    # Every ball in the hull has its centre in it, so within the box |x_k| <= 1 of ``unit``.
    ball = largest_ball(eq[:, :3], -eq[:, 3], box=1.0)
    if ball is None:
        return math.inf, None
    return max(ball.bound, 0.0) * scale * (1.0 + BOUND_SAFETY_REL), centre + scale * ball.centre


# ---------------------------------------------------------------------------------------------


class _Search:
    """The best certified ball so far and the box search that bounds all others."""

    def __init__(self, v: np.ndarray, f: np.ndarray):
        self.v, self.f = v, f
        self.tri = v[f]  # (m, 3, 3)
        self._group: np.ndarray | None = None
        n = np.cross(self.tri[:, 1] - self.tri[:, 0], self.tri[:, 2] - self.tri[:, 0])
        self.normal = n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        self.radius = 0.0
        self.centre: np.ndarray | None = None
        self.upper_radius = math.inf
        self.boxes = 0
        self._ascended_at = 0.0

    @property
    def group(self) -> np.ndarray:
        """``(m,)`` int64: the flat convex polygon each triangle belongs to (computed once)."""
        if self._group is None:
            self._group = _convex_faces(self.v, self.f)
        return self._group

    # --- lower bound ---------------------------------------------------------------------------

    def seed(self) -> None:
        """Candidate centres, grown by the ascent: ``inscribed_ball``'s (inward rays from face
        centroids, compass search), and the midpoints of rays cast along the inward bisectors of
        edges: a ball in the corner of a thin wall touches an edge, and on a wall of constant
        thickness neither a face's ray nor the ascent leaves the flat middle for the corner. The
        best few of the reflex edges and of the convex ones, a radius apart, are grown."""
        v, f = self.v, self.f
        radius, centre = inscribed_ball(v, f, _MAX_SEEDS)
        if radius > 0.0 and self.offer(np.asarray(centre, dtype=np.float64)):
            self.ascend()
        size = float(np.ptp(v, axis=0).max())
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        third = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])  # the vertex opposite each edge
        owner = np.tile(np.arange(len(f)), 3)
        order = np.lexsort((e[:, 1], e[:, 0]))
        e, owner, third = e[order], owner[order], third[order]
        pair = np.flatnonzero(np.all(e[1:] == e[:-1], axis=1))  # e[k] == e[k + 1]: one edge
        # Reflex: the far vertex of one face lies outside the other face's plane.
        lift = np.einsum("ij,ij->i", self.normal[owner[pair]], v[third[pair + 1]] - v[e[pair, 0]])
        # Flat edges (a wall's diagonals, a cap's fan) cast the faces' own rays: skipped.
        bent = (
            np.einsum("ij,ij->i", self.normal[owner[pair]], self.normal[owner[pair + 1]])
            < 1 - FLAT_EDGE_COS
        )
        for edges in (pair[bent & (lift > 0.0)], pair[bent & (lift <= 0.0)]):
            self._grow_edge_seeds(e, owner, evenly_strided(edges, _MAX_SEEDS), size)

    def _grow_edge_seeds(self, e, owner, pair, size) -> None:
        bisector = -(self.normal[owner[pair]] + self.normal[owner[pair + 1]])
        length = np.linalg.norm(bisector, axis=1)
        ok = length > MIN_BISECTOR
        o = 0.5 * (self.v[e[pair, 0]] + self.v[e[pair, 1]])[ok]
        d = bisector[ok] / length[ok, None]
        t = ray_hits(o, d, self.v, self.f, RAY_SKIP_REL * size)
        hit = np.isfinite(t)
        points = o[hit] + 0.5 * t[hit, None] * d[hit]
        if len(points) == 0:
            return
        dist = point_distances(points, self.v, self.f)
        chosen: list[np.ndarray] = []
        for k in np.argsort(-dist):
            if len(chosen) == _ASCENTS or dist[k] <= 0.5 * self.radius:
                break  # an ascent grows a ball by a few percent, not by half
            if any(np.linalg.norm(points[k] - c) < dist[k] for c in chosen):
                continue
            chosen.append(points[k])
            if abs(winding_numbers(points[k : k + 1], self.v, self.f)[0]) > 0.5:
                self.ascend(points[k], float(dist[k]))

    def offer(self, x: np.ndarray, distance: float | None = None) -> bool:
        """Keep ``x`` as the centre when it is inside and farther from the surface than the
        current centre. Returns True when kept."""
        x = np.asarray(x, dtype=np.float64).reshape(1, 3)
        d = float(point_distances(x, self.v, self.f)[0]) if distance is None else distance
        if d <= self.radius:
            return False
        if abs(winding_numbers(x, self.v, self.f)[0]) <= 0.5:
            return False
        self.radius, self.centre = d, x[0].copy()
        return True

    def ascend(self, x=None, r=None, max_steps: int = 60) -> None:
        """Grow the ball at ``x`` (inside, radius ``r``; default the current one) by successive
        linear programs (see ``_ascent_step``) and keep it when it beats the current one."""
        if x is None:
            if self.centre is None:
                return
            x, r = self.centre, self.radius
        for _ in range(max_steps):
            y = _ascent_step(self.v, self.f, x, r)
            if y is None:
                break
            ry = float(point_distances(y.reshape(1, 3), self.v, self.f)[0])
            if ry <= r * (1.0 + ASCENT_REL):
                break
            x, r = y, ry
        if r > self.radius:
            self.offer(x, r)  # the steps stay inside; the winding number says so once more
        self._ascended_at = self.radius

    # --- upper bound ---------------------------------------------------------------------------

    def branch_and_bound(
        self, *, upper_radius: float, decide_at: float | None, rel_gap: float, max_boxes: int
    ) -> None:
        self.upper_radius = upper_radius
        if max_boxes <= 0 or upper_radius <= self.radius * (1.0 + rel_gap):
            return
        lo, hi = self.v.min(axis=0), self.v.max(axis=0)
        heap: list = []
        count = 0

        def push(blo, bhi):
            nonlocal count
            bound, axis = self._box_upper(blo, bhi)
            count += 1
            heapq.heappush(heap, (-bound, count, blo, bhi, axis))

        push(lo, hi)
        while heap:
            top = -heap[0][0]
            if top <= self.radius * (1.0 + rel_gap) or self.boxes >= max_boxes:
                break
            if decide_at is not None and top <= decide_at:
                break
            if self.radius > self._ascended_at * (1.0 + 0.1 * rel_gap):
                self.ascend()
                continue
            _, _, blo, bhi, axis = heapq.heappop(heap)
            mid = 0.5 * (blo[axis] + bhi[axis])
            left_hi, right_lo = bhi.copy(), blo.copy()
            left_hi[axis], right_lo[axis] = mid, mid
            push(blo, left_hi)
            push(right_lo, bhi)
        top = -heap[0][0] if heap else self.radius
        self.upper_radius = min(upper_radius, max(top, self.radius))

    def _box_upper(self, lo: np.ndarray, hi: np.ndarray) -> tuple[float, int]:
        """Upper bound on ``d`` over the solid's points in the box, and the axis to split."""
        self.boxes += 1
        c = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        h = float(np.sqrt(half @ half))
        dist, _ = closest_points_on_triangles(c, self.v, self.f)
        d = float(dist.min())
        w = abs(float(winding_numbers(c.reshape(1, 3), self.v, self.f)[0]))
        if w > 0.5 and d > self.radius:
            self.offer(c, d)
        # Outside, every point of the solid in the box is at most h - d from the surface; a
        # winding number far from 0 and 1 (a centre on the surface) proves neither side.
        bound = (-d if w < 0.1 else d) + h
        longest = int(np.argmax(hi - lo))
        if bound <= self.radius or h <= 0.0:
            return bound, longest
        near = np.argpartition(dist, min(_NEAREST, len(dist) - 1))[:_NEAREST]
        # The flat convex polygons those triangles belong to: the distance to one is convex too,
        # and on a wall split into triangles it is the plane's distance across the diagonals.
        groups = np.unique(self.group[near])
        members = np.flatnonzero(np.isin(self.group, groups))
        corners = np.array(
            [
                [(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                for i in (0, 1)
                for j in (0, 1)
                for k in (0, 1)
            ]
        )
        per_tri = _triangle_distances(corners, self.tri[members])  # (8, t)
        slot = np.searchsorted(groups, self.group[members])
        g = np.full((8, len(groups)), np.inf)
        for c in range(8):
            np.minimum.at(g[c], slot, per_tri[c])
        convex, weights = _best_combination(g)
        if convex > self.radius and len(groups) > 2:
            convex, weights = min((convex, weights), _lp_combination(g), key=lambda t: t[0])
        if convex >= bound or w < 0.1:  # outside, only the Lipschitz bound can reach below d
            return min(bound, convex), longest
        # Split across the axis along which the weighted polygons' distances change most: a
        # direction parallel to all of them (a shell's axis) gains nothing from a cut.
        used = groups[weights > DUAL_WEIGHT_MIN]
        slope = np.abs(self.normal[used]).max(axis=0) * (hi - lo)
        return convex, int(np.argmax(slope + 1e-3 * (hi - lo)))


def _best_combination(g: np.ndarray) -> tuple[float, np.ndarray]:
    """``min over w of max over corners of g @ w`` over single triangles and pairs.

    Parameters
    ----------
    g : (8, k) float64
        Distance from each box corner to each candidate triangle.

    Returns
    -------
    bound : float
    weights : (k,) float64
        The combination that gives it.
    """
    single = g.max(axis=0)
    best_i = int(np.argmin(single))
    k = g.shape[1]
    bound, weights = float(single[best_i]), np.eye(k)[best_i]
    if k < 2:
        return bound, weights
    i, j = np.triu_indices(k, 1)
    a, b = g[:, i], g[:, j]  # (8, p): value w * a + (1 - w) * b = b + w (a - b)
    slope = a - b
    # The maximum over corners of lines in w is convex; its minimum is at w = 0, 1 or where two
    # corner lines cross.
    s1, s2 = slope[:, None, :], slope[None, :, :]
    c1, c2 = b[:, None, :], b[None, :, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (c2 - c1) / (s1 - s2)  # (8, 8, p)
    w = np.where(np.isfinite(w) & (w > 0.0) & (w < 1.0), w, 0.0).reshape(64, -1)
    w = np.concatenate([w, np.ones((1, w.shape[1]))], axis=0)  # (65, p)
    top = (b[None, :, :] + w[:, None, :] * slope[None, :, :]).max(axis=1)  # (65, p)
    pick = np.argmin(top, axis=0)
    best = top[pick, np.arange(top.shape[1])]
    q = int(np.argmin(best))
    if best[q] < bound:
        wq = w[pick[q], q]
        bound, weights = float(best[q]), np.zeros(k)
        weights[i[q]], weights[j[q]] = wq, 1.0 - wq
    return bound, weights


def _lp_combination(g: np.ndarray) -> tuple[float, np.ndarray]:
    """``min over w of max over corners of g @ w`` over all weights (a linear program)."""
    from scipy.optimize import linprog

    n8, k = g.shape
    # Variables (w_1..w_k, t): minimise t with g w <= t, sum w = 1, w >= 0.
    lp = linprog(
        np.r_[np.zeros(k), 1.0],
        A_ub=np.c_[g, -np.ones(n8)],
        b_ub=np.zeros(n8),
        A_eq=np.r_[np.ones(k), 0.0].reshape(1, -1),
        b_eq=[1.0],
        bounds=[(0.0, None)] * k + [(None, None)],
        method="highs",
    )
    if lp.status != 0:
        return math.inf, np.eye(k)[0]
    w = np.maximum(lp.x[:k], 0.0)
    w /= w.sum()
    # Recomputed from the weights (any weights give a bound): the solver's t is not trusted.
    return float((g @ w).max()), w


def _convex_faces(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Label each triangle with a flat convex polygon of the surface it belongs to.

    Neighbouring triangles (sharing an edge) that lie in one plane are joined while their union
    stays convex (its area equals its convex hull's); a triangle alone is its own polygon.
    Returns ``(m,)`` int64 labels.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(f)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(n, axis=1)
    unit = n / np.where(area2 > 0, area2, 1.0)[:, None]
    offset = np.einsum("ij,ij->i", unit, tri[:, 0])
    size = float(np.ptp(v, axis=0).max()) or 1.0
    # Edges shared by two triangles.
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(m), 3)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, owner = e[order], owner[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = owner[:-1][same], owner[1:][same]
    flat = (
        (area2[a] > 0)
        & (area2[b] > 0)
        & (np.einsum("ij,ij->i", unit[a], unit[b]) >= 1.0 - COPLANAR_COS)
        & (np.abs(offset[a] - offset[b]) <= COPLANAR_OFFSET_REL * size)
    )
    graph = coo_matrix((np.ones(int(flat.sum())), (a[flat], b[flat])), shape=(m, m))
    _, label = connected_components(graph, directed=False)
    label = label.astype(np.int64)
    # A group whose union is not convex (a ring, an L) falls apart into single triangles.
    out = np.arange(m, dtype=np.int64)
    counts = np.bincount(label, minlength=m)
    for g in np.flatnonzero(counts > 1):
        members = np.flatnonzero(label == g)
        if len(members) > 64 or _is_convex_polygon(tri[members], unit[members[0]]):
            if len(members) <= 64:
                out[members] = members[0]
    return out


def _is_convex_polygon(tri: np.ndarray, normal: np.ndarray) -> bool:
    """True when coplanar triangles ``(t, 3, 3)`` cover a convex region (area = hull area)."""
    from scipy.spatial import ConvexHull, QhullError

    axis = np.eye(3)[int(np.argmin(np.abs(normal)))]
    e1 = np.cross(normal, axis)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    pts = tri.reshape(-1, 3)
    uv = np.c_[pts @ e1, pts @ e2]
    try:
        hull = ConvexHull(uv).volume
    except QhullError:
        return False
    t = uv.reshape(-1, 3, 2)
    d1, d2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]).sum()
    return abs(area - hull) <= CONVEX_AREA_REL * hull


def _triangle_distances(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Exact distance from each point ``(P, 3)`` to each triangle ``(T, 3, 3)``: ``(P, T)``.

    Inside the prism over the triangle it is the distance to the plane, elsewhere the least
    distance to the three edges (also for degenerate triangles, which have no plane)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)  # (T, 3)
    nn = np.einsum("ij,ij->i", n, n)
    x = p[:, None, :]  # (P, 1, 3)
    inside = np.ones((len(p), len(tri)), dtype=bool)
    edges = []
    for s, e in ((a, b), (b, c), (c, a)):
        ed = e - s
        inside &= np.einsum("ptj,tj->pt", np.cross(ed, x - s), n) >= 0.0
        ee = np.maximum(np.einsum("ij,ij->i", ed, ed), 1e-300)
        t = np.clip(np.einsum("ptj,tj->pt", x - s, ed) / ee, 0.0, 1.0)
        edges.append(np.linalg.norm(x - (s + t[..., None] * ed), axis=2))
    out = np.minimum(np.minimum(edges[0], edges[1]), edges[2])
    ok = nn > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        plane = np.abs(np.einsum("ptj,tj->pt", x - a, n)) / np.sqrt(nn)
    use = inside & ok[None, :]
    out[use] = np.minimum(out[use], plane[use])
    return out


def evenly_strided(items: np.ndarray, limit: int) -> np.ndarray:
    """At most ``limit`` of ``items``, evenly strided."""
    return items if len(items) <= limit else items[:: -(-len(items) // limit)]


def _ascent_step(v: np.ndarray, f: np.ndarray, x: np.ndarray, r: float) -> np.ndarray | None:
    """One linear program: maximise ``rho`` subject to ``(y - q_i) . u_i >= rho`` for every
    triangle ``i`` near ``x`` (``q_i`` its closest point to ``x``, ``u_i`` the unit direction from
    it) and ``|y - x|_inf <= r``. Each constraint bounds the distance from ``y`` to triangle ``i``
    from below (the triangle lies behind the plane through ``q_i`` normal to ``u_i``), and every
    triangle the step could reach is among them, so ``y`` stays inside. None when it fails."""
    dist, q = closest_points_on_triangles(x, v, f)
    keep = (dist <= r * (1.0 + 2.0 * math.sqrt(3.0))) & (dist > 0.0)
    if not keep.any() or not r > 0.0:
        return None
    u = (x - q[keep]) / dist[keep, None]
    # In the step d = y - x: -u_i . d + rho <= u_i . (x - q_i), |d_k| <= r.
    ball = largest_ball(-u, np.einsum("ij,ij->i", u, x - q[keep]), box=r)
    if ball is None:
        return None
    return x + ball.centre
