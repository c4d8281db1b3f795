"""Candidate part pairs -> exact verdicts on the real meshes.

The convex filter before this stage only says which part pairs *may* come within reach
(tolerance + clearance). Here the real triangles decide:

1. the triangles of each mesh whose boxes come within reach of the other mesh are paired through a
   bounding-volume hierarchy, and every pair's exact distance is computed (compiled C++, float64,
   both meshes re-centred on a common point so coordinates far from the origin keep their digits);
2. surfaces within the tolerance meet: when both meshes are closed, the shared solid is computed
   with manifold3d and its thickness (``depth``, the largest ball inside) tells interference from
   touching: touching only when it is *proven* no thicker than the tolerance (faces resting on
   faces leave a sliver at most), interference otherwise (see ``meshcheck.verify.depth``);
3. surfaces farther apart may still belong to one part buried inside the other: one point of every
   connected shell is tested with the winding number of the other mesh;
4. otherwise the pair is a clearance finding when the true distance is below the clearance, and
   clear when not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from .. import results
from ..geometry.triangles import (
    box_pairs,
    pair_distances,
    placed_surface_distance,
    triangle_boxes,
    winding_numbers,
)
from ..mesh import check_boolean_room, is_closed, manifold_solid, outward_faces
from ..results import PairVerdict, Solid, Verdict
from .depth import depth_bounds, evenly_strided

# Points tested with winding numbers (each costs one pass over the other mesh's triangles): one per
# shell for burial (a triangle soup can have a shell per triangle), and the surface-only probes.
_MAX_SHELL_PROBES = 20000
_MAX_SURFACE_PROBES = 4096


def verify_pair(
    a: trimesh.Trimesh,
    b: trimesh.Trimesh,
    *,
    tolerance: float,
    clearance: float | None,
    surfaces_apart: bool = False,
    memo: dict | None = None,
) -> PairVerdict:
    """Decide whether two meshes interfere, touch, come closer than ``clearance``, or are clear.

    Parameters
    ----------
    a, b : trimesh.Trimesh
        The two parts, world coordinates, model units.
    tolerance : float
        Overlaps thinner than this and gaps narrower than this count as touching, model units.
    clearance : float or None
        Report a clearance finding when the true distance is below this, model units.
    surfaces_apart : bool
        The caller has proven that the surfaces stay farther apart than the reach
        (``tolerance + clearance``); only a part buried inside the other remains to be checked.
    memo : dict, optional
        Per-mesh data that does not depend on the pair (the vertices standing for the connected
        shells), kept across calls: pass one dict, empty at first, for all the pairs of a run.
        Meshes are keyed by ``id``, so they must stay alive and unchanged while it is in use.

    Returns
    -------
    PairVerdict
        ``interference`` when the parts share a solid thicker than ``tolerance`` (including a part
        buried inside the other with no surfaces crossing), or, for a mesh that is not closed, when
        the surfaces cross by more than ``tolerance``; ``touching`` when they meet within
        ``tolerance`` otherwise; ``clearance`` when ``tolerance < distance < clearance``;
        ``clear`` otherwise.

    Examples
    --------
    >>> a = trimesh.creation.box(extents=[1, 1, 1])
    >>> b = trimesh.creation.box(extents=[1, 1, 1]).apply_translation([0.7, 0, 0])
    >>> v = verify_pair(a, b, tolerance=1e-6, clearance=None)
    >>> str(v.status), round(v.depth, 6), round(v.volume, 6)
    ('interference', 0.3, 0.3)
    """
    tolerance = float(tolerance)
    reach = tolerance + (float(clearance) if clearance else 0.0)
    meshes = _recentred(a, b, {} if memo is None else memo)
    if surfaces_apart:
        if _is_buried(meshes):
            return _interference(meshes, tolerance=tolerance, distance=0.0, near=None)
        return PairVerdict(Verdict.CLEAR, math.inf, is_surface_only=not meshes.is_closed)

    near = _near_pairs(meshes, reach)
    distance = float(near.distance.min()) if len(near.distance) else math.inf
    if distance <= tolerance:
        return _interference(meshes, tolerance=tolerance, distance=distance, near=near)
    if _is_buried(meshes):
        return _interference(meshes, tolerance=tolerance, distance=0.0, near=near)
    if clearance is not None and distance < clearance:
        return _clearance_verdict(meshes, near, distance)
    return PairVerdict(Verdict.CLEAR, distance, is_surface_only=not meshes.is_closed)


def surface_distance(
    a: trimesh.Trimesh,
    b: trimesh.Trimesh,
    *,
    reach: float,
    surfaces_apart: bool = False,
    memo: dict | None = None,
    enough: float | None = None,
) -> float:
    """The exact distance between two meshes' surfaces when it is within ``reach``; 0 when a
    shell of one lies inside the other; ``inf`` otherwise (farther apart than ``reach``).

    Parameters
    ----------
    a, b : trimesh.Trimesh
        The two parts, world coordinates, model units.
    reach : float
        Model units.
    surfaces_apart : bool
        The caller has proven that the surfaces stay farther apart than ``reach``.
    memo : dict, optional
        As for ``verify_pair``.
    enough : float, optional
        A distance (at most ``reach``) that answers the caller: the first triangle pair found
        within it, nearest boxes first, gives its distance, not the least one. Two surfaces
        resting on each other then cost a few pairs, not every pair along the contact.

    Examples
    --------
    >>> a = trimesh.creation.box(extents=[1, 1, 1])
    >>> b = trimesh.creation.box(extents=[1, 1, 1]).apply_translation([1.25, 0, 0])
    >>> surface_distance(a, b, reach=0.2), round(surface_distance(a, b, reach=0.3), 9)
    (inf, 0.25)
    """
    meshes = _recentred(a, b, {} if memo is None else memo)
    if not surfaces_apart and enough is not None:
        found = _first_within(meshes, enough)
        if found is not None:
            return found
    distance = math.inf
    if not surfaces_apart:
        near = _near_pairs(meshes, float(reach))
        if len(near.distance) and float(near.distance.min()) <= reach:
            distance = float(near.distance.min())
    if distance > 0.0 and _is_buried(meshes):
        return 0.0
    return distance


def first_within(
    a: trimesh.Trimesh, b: trimesh.Trimesh, distance: float, *, memo: dict | None = None
) -> float | None:
    """The distance of the first triangle pair of ``a`` and ``b`` found within ``distance``
    (nearest boxes first: ``surface_distance``'s ``enough``), None when none is: the first
    step of ``surface_distance``, milliseconds where the surfaces meet."""
    return _first_within(_recentred(a, b, {} if memo is None else memo), distance)


def _first_within(meshes: _CentredPair, distance: float) -> float | None:
    """``first_within`` on two meshes already re-centred (``_recentred``)."""
    found, _ = placed_surface_distance(
        meshes.va, meshes.fa, meshes.vb, meshes.fb, np.eye(4), float(distance), settle=True
    )
    return found if found <= distance else None


# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _CentredPair:
    """Both meshes, re-centred on ``origin`` (world = local + origin)."""

    va: np.ndarray
    fa: np.ndarray
    vb: np.ndarray
    fb: np.ndarray
    origin: np.ndarray
    keys: tuple  # per mesh: (id of the caller's mesh, faces flipped?), the key into ``memo``
    memo: dict  # see ``verify_pair``
    is_closed: bool  # both meshes closed (then their faces are wound outward)


def _recentred(a: trimesh.Trimesh, b: trimesh.Trimesh, memo: dict) -> _CentredPair:
    """Both meshes as float64 arrays re-centred on a point between them; closed ones wound
    outward (manifold3d and the inward rays want that)."""
    is_closed = _is_closed(a) and _is_closed(b)
    va, fa = np.asarray(a.vertices, dtype=np.float64), np.asarray(a.faces, dtype=np.int64)
    vb, fb = np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces, dtype=np.int64)
    origin = _common_origin(va, vb)
    va, vb = va - origin, vb - origin
    flipped = (False, False)
    if is_closed:
        flipped = (_is_inward(a, memo), _is_inward(b, memo))
        fa = fa[:, ::-1].copy() if flipped[0] else fa
        fb = fb[:, ::-1].copy() if flipped[1] else fb
    keys = ((id(a), flipped[0]), (id(b), flipped[1]))
    return _CentredPair(va, fa, vb, fb, origin, keys, memo, is_closed)


def _clearance_verdict(m: _CentredPair, near: _Near, distance: float) -> PairVerdict:
    """A clearance finding: the two closest points, their box and its centre, world frame."""
    k = int(np.argmin(near.distance))
    p, q = near.point_a[k] + m.origin, near.point_b[k] + m.origin
    where = results.Location(0.5 * (p + q), np.minimum(p, q), np.maximum(p, q))
    return PairVerdict(
        Verdict.CLEARANCE,
        distance,
        location=where,
        is_surface_only=not m.is_closed,
        closest=(p, q),
    )


@dataclass(frozen=True)
class _Near:
    """Triangle pairs within reach and their exact distances (local frame)."""

    pairs: np.ndarray  # (k, 2) int64: face of a, face of b
    distance: np.ndarray  # (k,) float64
    point_a: np.ndarray  # (k, 3) float64
    point_b: np.ndarray  # (k, 3) float64
    strength: np.ndarray  # (k,) float64: how far crossing triangles pass through each other


def _is_closed(mesh: trimesh.Trimesh) -> bool:
    return is_closed(mesh)


def _is_inward(mesh: trimesh.Trimesh, memo: dict) -> bool:
    """True when a closed mesh is wound inward (negative signed volume), decided once per mesh
    and kept in ``memo``: in the mesh's own frame (re-centred on its box), so the answer is the
    mesh's alone, whichever pair asks first and in whichever process."""
    key = ("inward", id(mesh))
    inward = memo.get(key)
    if inward is None:
        v = np.asarray(mesh.vertices, dtype=np.float64)
        f = np.asarray(mesh.faces, dtype=np.int64)
        centre = 0.5 * (v.min(axis=0) + v.max(axis=0)) if len(v) else np.zeros(3)
        inward = memo[key] = outward_faces(v - centre, f) is not f
    return inward


def _common_origin(va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """A point between the two meshes: the centre of their boxes' overlap (or of the gap)."""
    lo = np.maximum(va.min(axis=0), vb.min(axis=0))
    hi = np.minimum(va.max(axis=0), vb.max(axis=0))
    return 0.5 * (lo + hi)


def _near_pairs(m: _CentredPair, reach: float) -> _Near:
    """Exact distances of the triangle pairs whose boxes come within ``reach`` of each other."""
    alo, ahi = triangle_boxes(m.va, m.fa)
    blo, bhi = triangle_boxes(m.vb, m.fb)
    # Only triangles near the other mesh's box enter the hierarchy.
    ia = np.flatnonzero(
        np.all((alo <= bhi.max(axis=0) + reach) & (ahi >= blo.min(axis=0) - reach), axis=1)
    )
    ib = np.flatnonzero(
        np.all((blo <= ahi.max(axis=0) + reach) & (bhi >= alo.min(axis=0) - reach), axis=1)
    )
    local = box_pairs(alo[ia], ahi[ia], blo[ib], bhi[ib], reach)
    pairs = np.stack([ia[local[:, 0]], ib[local[:, 1]]], axis=1).astype(np.int64)
    dist, pa, pb, strength = pair_distances(m.va, m.fa, m.vb, m.fb, pairs)
    return _Near(pairs, dist, pa, pb, strength)


def _shell_points(v: np.ndarray, f: np.ndarray, memo: dict, key) -> np.ndarray:
    """One vertex of every connected shell of a mesh, ``(s, 3)``; the choice of vertices is kept
    in ``memo`` under ``("shells", key)``."""
    index = memo.get(("shells", key))
    if index is None:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        used = np.unique(f)
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        n = len(v)
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
        _, first = np.unique(labels[used], return_index=True)
        index = memo[("shells", key)] = evenly_strided(used[first], _MAX_SHELL_PROBES)
    return v[index]


def _is_buried(m: _CentredPair) -> bool:
    """True when a shell of one mesh lies inside the other (winding number above one half, in
    magnitude: an inside-out mesh has winding number -1 inside)."""
    for v, f, ov, of, key in (
        (m.va, m.fa, m.vb, m.fb, m.keys[0]),
        (m.vb, m.fb, m.va, m.fa, m.keys[1]),
    ):
        points = _shell_points(v, f, m.memo, key)
        lo, hi = ov.min(axis=0), ov.max(axis=0)
        inside_box = np.all((points >= lo) & (points <= hi), axis=1)
        if inside_box.any() and np.any(np.abs(winding_numbers(points[inside_box], ov, of)) > 0.5):
            return True
    return False


def _manifold(v: np.ndarray, f: np.ndarray):
    check_boolean_room(len(f), "boolean")  # before manifold3d, which crashes when it runs out
    return manifold_solid(v, f)


def shared_solid(
    va: np.ndarray, fa: np.ndarray, vb: np.ndarray, fb: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """Boolean intersection of two closed meshes with manifold3d.

    Parameters
    ----------
    va, vb : (n, 3) float64
        Vertices, any common frame.
    fa, fb : (m, 3) int64
        Faces, outward wound.

    Returns
    -------
    (vertices (p, 3) float64, faces (q, 3) int64), or None when manifold3d rejects a mesh.
    """
    sa, sb = _manifold(va, fa), _manifold(vb, fb)
    if sa is None or sb is None:
        return None
    out = (sa ^ sb).to_mesh64()
    v = np.asarray(out.vert_properties, dtype=np.float64)[:, :3].reshape(-1, 3)
    f = np.asarray(out.tri_verts, dtype=np.int64).reshape(-1, 3)
    return v, f


def _volume_centroid(v: np.ndarray, f: np.ndarray) -> tuple[float, np.ndarray]:
    """Volume and centroid of a closed outward mesh (signed tetrahedra from its first vertex)."""
    base = v[0]
    a, b, c = v[f[:, 0]] - base, v[f[:, 1]] - base, v[f[:, 2]] - base
    vol6 = np.einsum("ij,ij->i", a, np.cross(b, c))
    total = vol6.sum()
    if total <= 0.0:
        return 0.0, v.mean(axis=0)
    centroid = base + (vol6[:, None] * (a + b + c)).sum(axis=0) / (4.0 * total)
    return float(total / 6.0), centroid


def solid_depth(v: np.ndarray, f: np.ndarray) -> float:
    """Thickness of a closed solid: the diameter of the largest ball inside it, model units.

    Two boxes overlapping by 0.3 share a slab 0.3 thick; a bolt 0.2 too big radially shares a
    tube whose wall is 0.2 thick: both give that. The value is the diameter of a ball shown to
    be inside (``depth.depth_bounds`` without its upper-bound search), so never more than the
    true depth.

    Parameters
    ----------
    v : (n, 3) float64
        Vertices, model units.
    f : (m, 3) int64
        Faces of a closed, outward-wound mesh.

    Returns
    -------
    depth : float
        Model units; 0 for an empty solid.
    """
    return depth_bounds(v, f, max_boxes=0).lower


def _interference(
    m: _CentredPair, *, tolerance: float, distance: float, near: _Near | None
) -> PairVerdict:
    """Interference or touching, for meshes that meet or where one may be buried in the other."""
    if m.is_closed:
        solid = shared_solid(m.va, m.fa, m.vb, m.fb)
        if solid is not None:
            return _solid_verdict(m, solid, tolerance=tolerance, distance=distance, near=near)
    return _surface_verdict(m, tolerance=tolerance, distance=distance, near=near)


def _solid_verdict(
    m: _CentredPair, solid, *, tolerance: float, distance: float, near
) -> PairVerdict:
    """Touching only when the shared solid is proven no thicker than the tolerance (an upper
    bound on its largest ball); a ball that merely failed to be found larger proves nothing,
    so anything short of that proof is an interference, reported with the largest ball shown
    to fit (which may then be below the tolerance)."""
    v, f = solid
    bounds = depth_bounds(v, f, decide_at=tolerance)
    if bounds.upper > tolerance:
        depth = bounds.lower
        volume, centroid = _volume_centroid(v, f)
        where = results.Location(
            centroid + m.origin, v.min(axis=0) + m.origin, v.max(axis=0) + m.origin
        )
        return PairVerdict(
            Verdict.INTERFERENCE,
            0.0,
            depth=depth,
            volume=volume,
            location=where,
            solid=Solid(v + m.origin, f) if len(f) else None,
        )
    return PairVerdict(Verdict.TOUCHING, distance, location=_contact_region(m, near, tolerance))


def _surface_verdict(m: _CentredPair, *, tolerance: float, distance: float, near) -> PairVerdict:
    """Verdict from surfaces alone: they interfere when they pass through each other by more
    than the tolerance, or when a surface lies deeper than that inside the other mesh."""
    if near is None:  # surfaces apart: only a buried shell brings us here
        lo = np.maximum(m.va.min(axis=0), m.vb.min(axis=0)) + m.origin
        hi = np.minimum(m.va.max(axis=0), m.vb.max(axis=0)) + m.origin
        where = results.Location(0.5 * (lo + hi), lo, hi)
        return PairVerdict(Verdict.INTERFERENCE, 0.0, location=where, is_surface_only=True)
    crossing = near.strength > tolerance
    if crossing.any():
        points = np.concatenate([near.point_a[crossing], near.point_b[crossing]]) + m.origin
        where = results.Location(points.mean(axis=0), points.min(axis=0), points.max(axis=0))
        return PairVerdict(Verdict.INTERFERENCE, 0.0, location=where, is_surface_only=True)
    deep = _deep_points(m, near, tolerance)
    if len(deep) or _is_buried(m):
        where = None
        if len(deep):
            deep = deep + m.origin
            where = results.Location(deep.mean(axis=0), deep.min(axis=0), deep.max(axis=0))
        return PairVerdict(Verdict.INTERFERENCE, 0.0, location=where, is_surface_only=True)
    return PairVerdict(
        Verdict.TOUCHING,
        distance,
        location=_contact_region(m, near, tolerance),
        is_surface_only=True,
    )


def _deep_points(m: _CentredPair, near: _Near, tolerance: float) -> np.ndarray:
    """Vertices and centroids of the triangles near the other mesh that lie inside it (winding
    number above one half) by more than the tolerance, local frame, ``(p, 3)``."""
    from ..geometry.triangles import point_distances

    found = []
    for col, (v, f, ov, of) in enumerate(((m.va, m.fa, m.vb, m.fb), (m.vb, m.fb, m.va, m.fa))):
        faces = np.unique(near.pairs[:, col])
        tri = v[f[faces]]
        points = evenly_strided(
            np.concatenate([tri.mean(axis=1), v[np.unique(f[faces])]]), _MAX_SURFACE_PROBES
        )
        inside = points[np.abs(winding_numbers(points, ov, of)) > 0.5]
        if len(inside):
            found.append(inside[point_distances(inside, ov, of) > tolerance])
    return np.concatenate(found) if found else np.empty((0, 3))


def _contact_region(
    m: _CentredPair, near: _Near | None, tolerance: float
) -> results.Location | None:
    """Where two meshes touch: the box around the overlaps of the boxes of the triangle pairs
    within the tolerance, and its centre (exact for the usual flat rectangles and rings)."""
    if near is None:
        return None
    touching = near.pairs[near.distance <= tolerance]
    if len(touching) == 0:
        return None
    ta, tb = m.va[m.fa[touching[:, 0]]], m.vb[m.fb[touching[:, 1]]]
    lo = (np.maximum(ta.min(axis=1), tb.min(axis=1)) - tolerance).min(axis=0)
    hi = (np.minimum(ta.max(axis=1), tb.max(axis=1)) + tolerance).max(axis=0)
    hi = np.maximum(lo, hi)
    return results.Location(0.5 * (lo + hi) + m.origin, lo + m.origin, hi + m.origin)
