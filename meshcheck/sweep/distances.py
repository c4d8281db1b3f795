"""Distances between two posed links: lower bounds from their convex pieces, many placements in
one compiled call, and the real meshes' exact distance when the pieces cannot decide.

Each link's geometry lives in its own frame (``LinkGeometry``), report units; a placement is a
(4, 4) transform of that frame into the robot's root frame.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry import (
    ConvexPack,
    concat_packs,
    pack_convex,
    placed_distances,
    query_pairs,
    repeat_pack,
)
from ..load import Body
from ..load.robot import Mechanism, Robot, link_transforms

#: Directions whose extreme vertices make a piece's coarse hull (an icosphere's vertices, 2
#: subdivisions: 162).
COARSE_SUBDIVISIONS = 2
#: Pieces with more hull vertices than this are coarsened for the box search: the PR2's
#: fingers and wrists (1,000 to 4,450 per piece) are; the panda's (up to 170) are not, as their
#: pads would cost more boxes than the fewer vertices save (bench/sweep.py: 57.6 s and 3
#: undecided pairs with every piece over 162 coarsened, against 41.0 s and 2 without).
COARSE_MIN_VERTICES = 500


def coarse_pieces(
    pieces: list[np.ndarray], *, min_vertices: int = COARSE_MIN_VERTICES
) -> tuple[list[np.ndarray], np.ndarray]:
    """Fewer-vertex stand-ins for convex pieces, each with a padding that restores the bound.

    A piece with more than ``min_vertices`` vertices (and more than the icosphere has
    directions) is replaced by its extreme vertices along those directions (a hull inside it),
    and ``pad`` is the largest distance of
    its vertices from that hull (exact, by GJK): the piece lies inside the coarse hull grown by
    ``pad``, so the coarse hulls' distance minus both pads is a lower bound on the pieces'
    distance. Posing a finger of 4,000 hull vertices costs 160 instead.

    Returns
    -------
    coarse : list of (k_i, 3) float64
    pad : (m,) float64
        0 for pieces kept as they are.
    """
    import trimesh

    directions = trimesh.creation.icosphere(subdivisions=COARSE_SUBDIVISIONS).vertices
    coarse, pads = [], []
    for piece in pieces:
        if len(piece) <= max(min_vertices, len(directions)):
            coarse.append(piece)
            pads.append(0.0)
            continue
        kept = piece[np.unique(np.argmax(piece @ directions.T, axis=0))]
        far = float(hull_distances(pack_convex([kept]), piece).max())
        size = float(np.ptp(piece, axis=0).max())
        # GJK's distances are exact to rounding; the margin covers that rounding.
        pads.append(max(far, 0.0) + 1e-9 * size)
        coarse.append(kept)
    return coarse, np.array(pads)


def hull_distances(pack: ConvexPack, points: np.ndarray) -> np.ndarray:
    """(N, m) each of ``points``' distance from each of ``pack``'s ``m`` hulls (GJK, exact to
    rounding; negative inside), in one compiled call."""
    single = pack_convex([np.zeros((1, 3))])
    placed = np.ascontiguousarray(points, dtype=np.float64)[:, None, :]
    both = concat_packs([pack, repeat_pack(single, placed, placed, placed)])
    m = len(pack.starts) - 1
    pairs = np.stack(
        [np.tile(np.arange(m), len(points)), np.repeat(np.arange(m, m + len(points)), m)], axis=1
    )
    res = query_pairs(both, pairs.astype(np.int64), tolerance=0.0, depth=False)
    return res.distance.reshape(len(points), m)


@dataclass(frozen=True)
class LinkGeometry:
    """A link's convex pieces and real meshes in its own frame (report units), and its parts.

    Attributes
    ----------
    pack : ConvexPack
        The coarse pieces the box search poses (``coarse_pieces``).
    radius : float
        The farthest piece point from the link frame's origin.
    parts : tuple of (int, (4, 4) float64)
        (body index, link frame -> body placement) of each of its parts.
    pad : (m,) float64
        Each coarse piece's padding: the piece lies within it of its hull.
    points : (n, 3) float64
        Every piece's hull vertices (the motion bound's geometry).
    hull : (k, 3) float64
        A few of them whose hull, grown by ``hull_pad``, holds them all.
    hull_pad : float
    vertices : (v, 3) float64
        The real meshes' vertices, link frame.
    faces : (f, 3) int64
        Their triangles.
    points_pad : float
        The link's geometry lies within this of the hull of ``points`` (0: ``points`` are its
        pieces' own vertices; an envelope's are padded, ``envelope.envelope``).
    """

    pack: ConvexPack
    radius: float
    parts: tuple[tuple[int, np.ndarray], ...]
    pad: np.ndarray
    points: np.ndarray
    hull: np.ndarray
    hull_pad: float
    vertices: np.ndarray
    faces: np.ndarray
    points_pad: float = 0.0


def link_geometries(
    robot: Robot,
    mech: Mechanism,
    bodies: Sequence[Body],
    pieces: dict[int, list[np.ndarray]],
    base: dict[str, float],
    scale: float,
    *,
    only: Collection[str] | None = None,
) -> dict[str, LinkGeometry]:
    """Each link's pieces and meshes in its own frame and its parts' offsets from it.

    Parameters
    ----------
    pieces : dict of int -> list of (n_i, 3) float64
        Each part's convex pieces, world coordinates at the pose ``base``.
    base : dict of str -> float
        Every movable joint's value at the run's pose.
    scale : float
        Report units per unit of the robot's lengths.
    only : collection of str, optional
        The links wanted (default every link with parts).
    """
    placed = link_transforms(robot, base)
    out = {}
    for link, ks in sorted(mech.parts.items()):
        if only is not None and link not in only:
            continue
        frame = placed[link].copy()
        frame[:3, 3] *= scale
        inverse = np.linalg.inv(frame)
        local = [p @ inverse[:3, :3].T + inverse[:3, 3] for k in ks for p in pieces[k]]
        parts = tuple((k, inverse @ bodies[k].transform) for k in ks)
        points = pack_convex(local, is_hull=True).points
        coarse, pad = coarse_pieces(local)
        radius = float(np.linalg.norm(points, axis=1).max())
        (hull,), (hull_pad,) = coarse_pieces([points], min_vertices=0)
        vertices, faces, count = [], [], 0
        for k, offset in parts:
            mesh = bodies[k].mesh
            vertices.append(np.asarray(mesh.vertices) @ offset[:3, :3].T + offset[:3, 3])
            faces.append(np.asarray(mesh.faces, dtype=np.int64) + count)
            count += len(mesh.vertices)
        out[link] = LinkGeometry(
            pack_convex(coarse, is_hull=True),
            radius,
            parts,
            pad,
            points,
            hull,
            float(hull_pad),
            np.vstack(vertices),
            np.vstack(faces),
        )
    return out


def piece_distances(
    pack_a,
    pack_b,
    ta,
    tb,
    reach: np.ndarray,
    pad_a=None,
    pad_b=None,
    *,
    settle: bool = False,
    work: list[int] | None = None,
):
    """Lower bounds on the distance between two links' pieces at E placements.

    Parameters
    ----------
    pack_a, pack_b : ConvexPack
        Each link's convex pieces in its own frame.
    ta, tb : (E, 4, 4) float64
        The links' placements.
    reach : (E,) float64
        Distances beyond which the exact value does not matter (answers above it are bounds).
    pad_a, pad_b : (m_a,), (m_b,) float64, optional
        Each piece stands for itself grown by this much (``coarse_pieces``); default 0.
    settle : bool
        Only whether each placement comes within ``reach`` matters: piece pairs are measured
        nearest boxes first, and the first that brings a placement within reach gives it that
        pair's distance (at most ``reach``, not the least) and no more GJK. The sweep's boxes
        split or close on this alone.
    work : list of one int, optional
        Gets the work done added (``geometry.placed_distances``).

    Returns
    -------
    lowest : (E,) float64
        For each placement, a lower bound on the distance between the two links' surfaces
        (exact when at most ``reach`` and nothing is padded): the smallest piece-pair signed
        distance less both pads; ``inf`` when every piece pair's boxes are farther apart than
        ``reach``. With ``settle``, a value at most ``reach`` is some piece pair's.
    """
    ma, mb = len(pack_a.starts) - 1, len(pack_b.starts) - 1
    pad_a = np.zeros(ma) if pad_a is None else pad_a
    pad_b = np.zeros(mb) if pad_b is None else pad_b
    lowest = np.full(len(ta), np.inf)
    near = spheres_within(pack_a, pack_b, ta, tb, reach, float(pad_a.max() + pad_b.max()))
    if np.any(near):  # pose only the placements whose links' spheres come within reach
        lowest[near], done = posed_distances(
            pack_a, pack_b, ta[near], tb[near], reach[near], pad_a, pad_b, settle=settle
        )
        if work is not None:
            work[0] += done
    return lowest


def spheres_within(pack_a, pack_b, ta, tb, reach: np.ndarray, pad: float) -> np.ndarray:
    """Which of E placements bring the two links' bounding spheres (grown by ``pad``) within
    ``reach`` (the others' pieces are farther apart than that: nothing need be posed)."""
    out = []
    for pack, t in ((pack_a, ta), (pack_b, tb)):
        centre = 0.5 * (pack.points.min(axis=0) + pack.points.max(axis=0))
        radius = float(np.linalg.norm(pack.points - centre, axis=1).max())
        out.append((t[:, :3, :3] @ centre + t[:, :3, 3], radius))
    (pa, ra), (pb, rb) = out
    return np.linalg.norm(pa - pb, axis=1) - ra - rb - pad <= reach


def posed_distances(
    pack_a, pack_b, ta, tb, reach, pad_a, pad_b, *, settle: bool = False
) -> tuple[np.ndarray, int]:
    """``piece_distances`` of placements whose links come near, and the work done: link b's
    pieces posed in link a's frame (distances do not change under the rigid motion of both,
    and a's pieces then serve every placement unmoved), the piece pairs whose boxes come
    within reach (plus pads) measured by GJK, in one compiled call
    (``geometry.placed_distances``)."""
    rotation = ta[:, :3, :3].transpose(0, 2, 1)
    relative = np.zeros((len(ta), 4, 4))
    relative[:, :3, :3] = rotation @ tb[:, :3, :3]
    relative[:, :3, 3] = np.einsum("eij,ej->ei", rotation, tb[:, :3, 3] - ta[:, :3, 3])
    relative[:, 3, 3] = 1.0
    return placed_distances(pack_a, pack_b, relative, reach, pad_a, pad_b, settle=settle)


def surface_distance(
    a: LinkGeometry,
    b: LinkGeometry,
    ta: np.ndarray,
    tb: np.ndarray,
    reach: float,
    *,
    settle: bool = False,
    work: list[int] | None = None,
) -> float:
    """The distance between two links' real surfaces placed by ``ta``, ``tb``, exact when at
    most ``reach`` (else a value above it; with ``settle``, some triangle pair's distance
    within it): link b's triangles placed in link a's frame, the triangle pairs whose boxes
    come within ``reach`` measured exactly, nearest first (``placed_surface_distance``); 0
    where surfaces cross. The work (triangle pairs measured, and the triangles boxed over 64)
    goes to ``work``."""
    from ..geometry.triangles import placed_surface_distance

    relative = np.linalg.solve(ta, tb)
    found, pairs = placed_surface_distance(
        a.vertices, a.faces, b.vertices, b.faces, relative, reach, settle=settle
    )
    if work is not None:
        work[0] += pairs + (len(a.faces) + len(b.faces)) // 64
    return found
