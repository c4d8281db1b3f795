"""Mechanisms: which parts are links of a robot, which links are adjacent, and (``--sweep``)
which link pairs collide never, sometimes or always over the joint ranges.
"""

from __future__ import annotations

import dataclasses
import glob
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .config import Approval
from .load import Body
from .load.files import URDF_EXTENSIONS
from .load.limits import Limits, read_file
from .load.robot import MOVABLE, Robot, adjacent_links, with_mimics
from .load.urdf import parse_robot

#: The reason adjacent links' findings are approved with (MoveIt's "Adjacent").
ADJACENT = "adjacent"


@dataclass(frozen=True)
class Mechanism:
    """One robot (a URDF, or the configuration's ``[[joint]]`` tables) and its links' parts.

    Attributes
    ----------
    robot : Robot
    parts : dict of str -> list of int
        Each link's parts, as indices into the run's bodies.
    units : str
        The unit of the robot's lengths: metres for a URDF, the report unit for ``[[joint]]``.
    adjacent : set of frozenset of str
        Link pairs joined by a joint (``load.robot.adjacent_links`` for a URDF).
    is_urdf : bool
        A URDF robot: every link pair is swept and goes to the SRDF. A mechanism of mesh parts
        sweeps only the pairs some joint moves relative to each other (the check itself judges
        the others at the pose).
    """

    robot: Robot
    parts: dict[str, list[int]]
    units: str = "m"
    adjacent: set = dataclasses.field(default_factory=set)
    is_urdf: bool = True

    def link_of(self) -> dict[int, str]:
        """The link of each of the robot's parts (index into the run's bodies)."""
        return {k: link for link, ks in self.parts.items() for k in ks}


def mechanisms(bodies: Sequence[Body], joints: Sequence = ()) -> list[Mechanism]:
    """The robots among the bodies (every URDF file, in the order their parts come), then the
    mechanism the configuration's ``[[joint]]`` tables (``joints``) make of mesh parts."""
    out = []
    by_path: dict[str, list[int]] = {}
    for k, body in enumerate(bodies):
        if os.path.splitext(body.path)[1].lower() in URDF_EXTENSIONS:
            by_path.setdefault(body.path, []).append(k)
    for path, ks in by_path.items():
        robot = parse_robot(path, read_file(path, _NO_LIMITS))
        node_link = {c.node: c.link for c in robot.collisions}
        parts: dict[str, list[int]] = {}
        for k in ks:
            node = bodies[k].name.rpartition("#")[2]
            parts.setdefault(node_link[node], []).append(k)
        out.append(Mechanism(robot, parts, adjacent=adjacent_links(robot)))
    if joints:
        from .load.joints import mesh_mechanism

        mesh = mesh_mechanism(bodies, joints)
        units = bodies[0].units
        out.append(Mechanism(mesh.robot, mesh.parts, units, mesh.adjacent, is_urdf=False))
    return out


def adjacent_approvals(bodies: Sequence[Body], found: Sequence[Mechanism]) -> list[Approval]:
    """An approval (reason ``ADJACENT``) for each pair of parts on adjacent links.

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts.
    found : sequence of Mechanism
        ``mechanisms(bodies)``.
    """
    out = []
    for mech in found:
        for pair in sorted(sorted(p) for p in mech.adjacent):
            a, b = pair
            for i in mech.parts.get(a, ()):
                for j in mech.parts.get(b, ()):
                    out.append(
                        Approval(glob.escape(bodies[i].name), glob.escape(bodies[j].name), ADJACENT)
                    )
    return out


def with_mechanisms(bodies: Sequence[Body], settings):
    """``settings`` with the approvals the robots among ``bodies`` bring: adjacent links'
    pairs (after the user's own rules, whose reasons win), unless ``settings.motion.adjacent``
    is off."""
    if not settings.motion.adjacent:
        return settings
    extra = adjacent_approvals(bodies, mechanisms(bodies, settings.motion.joints))
    if not extra:
        return settings
    return settings.replace(approvals=(*settings.approvals, *extra))


_NO_LIMITS = Limits(max_file_bytes=1 << 62)  # the URDF was read once already, within the limits


# --------------------------------------------------------------------------------------------
# The sweep: never / sometimes / always over the joint ranges

#: Boxes of joint values one link pair may evaluate before it is left undecided (the panda's
#: link 0 and link 4 need 71,579; bench/sweep.py on the PR2 sets the time against 10,000
#: python-fcl samples).
MAX_BOXES = 100_000
#: Boxes evaluated in one compiled call.
BATCH = 1024
#: Boxes whose motion bound is below this fraction of the smaller link's size, and whose
#: coarse pieces do not prove them apart, are measured on the real meshes' triangles.
FINE_REACH = 0.02
#: Poses drawn (fixed seed) to look for a witness before the proof starts, and how many of the
#: closest are re-checked on the real meshes.
SAMPLES = 256
SAMPLE_CHECKS = 4
#: Candidate witnesses re-checked on the real meshes per link pair, deepest piece overlap first.
MAX_WITNESS_CHECKS = 24
#: A pair not decided after this many boxes looks for a witness by descending the pieces'
#: distance from the nearest box centres (``_descent_witness``): how many, steps, tries.
DESCENT_AFTER = 4096
DESCENT_STARTS = 8
DESCENT_STEPS = 10
DESCENT_TRIES = 32

NEVER, SOMETIMES, ALWAYS, UNDECIDED = "never", "sometimes", "always", "undecided"
STATUSES = (NEVER, SOMETIMES, ALWAYS, UNDECIDED)


@dataclass(frozen=True)
class PairSweep:
    """How one pair of links relates over the joint ranges.

    Attributes
    ----------
    a, b : str
        Link names, ``a < b``.
    status : str
        ``never`` (proven: every box of joint values certified apart by more than the touching
        tolerance, see ``sweep_mechanism``), ``sometimes`` (a witness pose where the real meshes
        interfere or touch), ``always`` (their relative placement does not move and they
        collide), or ``undecided`` (neither proven within the resolution and ``MAX_BOXES``).
    joints : tuple of str
        The swept joints that move the pair relative to each other.
    witness : dict of str -> float or None
        For ``sometimes``: the free joints' values of the worst pose found, the witness
        (radians; metres for a URDF's slide, report units for a ``[[joint]]`` slide; the other
        joints at the run's pose): candidates (the seeded samples, then each batch of box
        centres) are re-checked deepest overlap of the links' convex pieces first, and the first
        the real meshes confirm is the witness (a bad pose, not a proven maximum of the depth).
        ``{}`` for ``always`` when nothing moves the pair.
    verdict : str or None
        The real meshes' status at the witness (``interference`` or ``touching``).
    boxes : int
        Boxes of joint values evaluated.
    is_adjacent : bool
        The links are joined by a joint (``load.robot.adjacent_links``).
    approval_reason : str or None
        For a mechanism of ``[[joint]]`` tables, the reason of the approval rule its two parts
        match (adjacent parts: ``ADJACENT``); its collision then does not fail the run.
    """

    a: str
    b: str
    status: str
    joints: tuple[str, ...] = ()
    witness: dict | None = None
    verdict: str | None = None
    boxes: int = 0
    is_adjacent: bool = False
    approval_reason: str | None = None

    def to_dict(self) -> dict:
        """The pair as the JSON report lists it (``pose``: the witness's joint values)."""
        return {
            "a": self.a,
            "b": self.b,
            "status": self.status,
            "adjacent": self.is_adjacent,
            "joints": list(self.joints),
            "pose": None if self.witness is None else dict(self.witness),
            "verdict": self.verdict,
            "approval_reason": self.approval_reason,
        }


@dataclass(frozen=True)
class _Link:
    """A link's convex pieces in its own frame (report units) and its parts."""

    pack: object  # ConvexPack: the coarse pieces the box search poses (``coarse_pieces``)
    radius: float  # farthest piece point from the link frame's origin
    parts: tuple[tuple[int, np.ndarray], ...]  # (body index, link frame -> body placement)
    pad: np.ndarray  # (m,) each coarse piece's padding: the piece lies within it of its hull
    points: np.ndarray  # (n, 3) every piece's hull vertices (the motion bound's geometry)
    hull: np.ndarray  # (k, 3) a few of them whose hull, grown by ``hull_pad``, holds them all
    hull_pad: float
    vertices: np.ndarray  # (v, 3) the real meshes' vertices, link frame
    faces: np.ndarray  # (f, 3) int64, their triangles


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

    from .geometry import pack_convex, query_pairs

    directions = trimesh.creation.icosphere(subdivisions=COARSE_SUBDIVISIONS).vertices
    coarse, pads = [], []
    for piece in pieces:
        if len(piece) <= max(min_vertices, len(directions)):
            coarse.append(piece)
            pads.append(0.0)
            continue
        kept = piece[np.unique(np.argmax(piece @ directions.T, axis=0))]
        pack = pack_convex([kept, *piece[:, None, :]])
        pairs = np.stack([np.zeros(len(piece), np.int64), np.arange(1, len(piece) + 1)], axis=1)
        res = query_pairs(pack, pairs, tolerance=0.0, depth=False)
        size = float(np.ptp(piece, axis=0).max())
        # GJK's distances are exact to rounding; the margin covers that rounding.
        pads.append(float(max(res.distance.max(), 0.0)) + 1e-9 * size)
        coarse.append(kept)
    return coarse, np.array(pads)


def _chain(robot: Robot, link: str) -> list:
    """Joints from the root down to ``link``."""
    by_child = {j.child: j for j in robot.joints}
    out = []
    while link in by_child:
        out.append(by_child[link])
        link = by_child[link].parent
    return out[::-1]


def _leader(robot: Robot, joint) -> tuple[str, float]:
    """(leading joint, multiplier): a mimic chain followed to the joint that leads it."""
    by_name = {j.name: j for j in robot.joints}
    multiplier = 1.0
    while joint.mimic is not None:
        multiplier *= joint.mimic[1]
        joint = by_name[joint.mimic[0]]
    return joint.name, multiplier


def _extent(robot: Robot, joint, swept: set[str], base: dict[str, float]) -> float:
    """Largest |value| a prismatic joint takes in the sweep, metres."""
    name, multiplier = _leader(robot, joint)
    offset = joint.mimic[2] if joint.mimic is not None else 0.0
    if name not in swept:
        return abs(base[joint.name])
    lead = next(j for j in robot.joints if j.name == name)
    return max(abs(multiplier * lead.lower + offset), abs(multiplier * lead.upper + offset))


def motion_weights(
    robot: Robot,
    pair: tuple[str, str],
    radius: dict[str, float],
    swept: set[str],
    base: dict[str, float],
    scale: float = 1.0,
    points: dict[str, np.ndarray] | None = None,
) -> dict[str, float]:
    """How far a unit change of each swept joint can move any point of either link of ``pair``.

    Moving leading joint ``k`` by ``dq`` moves every point of the two links by at most
    ``w[k] * |dq|`` (report units), in any configuration of the sweep: a revolute joint turns
    the points below it about its axis, which passes through its origin ``o_k``, so a point ``p``
    moves by at most ``|p - o_k| * |dq|``, and ``|p - o_k|`` is bounded by the joint offsets and
    slide extents down to the link plus the link's ``radius``; a prismatic joint moves them by
    ``|dq|``. Joints below the links' common ancestor move one link each; the distance between
    the links therefore changes by at most ``sum_k w[k] * |dq_k|`` (summed along a straight path
    in joint space).

    Parameters
    ----------
    radius : dict of str -> float
        Each link's farthest geometry point from its frame's origin, report units.
    swept : set of str
        Leading joints that move.
    base : dict of str -> float
        Every movable joint's value where it does not move (``joint_values``).
    scale : float
        Report units per metre.
    points : dict of str -> (n, 3) float64, optional
        Each link's geometry (hull vertices) in its own frame, report units: the joints that
        turn a link with only fixed joints between get the exact largest distance of its points
        from their axis line, and the joints above a bound from it (``_chain_weights``).
    """
    out: dict[str, float] = {}
    for chain, link in zip(_below_common(robot, pair), pair, strict=True):
        local = None if points is None else points.get(link)
        for joint, weight in _chain_weights(robot, chain, radius[link], local, swept, base, scale):
            name, multiplier = _leader(robot, joint)
            out[name] = out.get(name, 0.0) + abs(multiplier) * weight
    return out


def _below_common(robot: Robot, pair: tuple[str, str]) -> tuple[list, list]:
    """The joints from the two links' common ancestor down to each link of ``pair``: only
    they move one link relative to the other."""
    a_chain, b_chain = _chain(robot, pair[0]), _chain(robot, pair[1])
    common = 0
    while common < min(len(a_chain), len(b_chain)) and a_chain[common] is b_chain[common]:
        common += 1
    return a_chain[common:], b_chain[common:]


def _chain_weights(robot, chain, radius, local, swept, base, scale):
    """(joint, bound on the speed of the link's points per unit of it) up one chain.

    Walking up from the link, the points are either rigid in the current frame (``local``,
    report units: only fixed joints passed) or known to lie within ``reach`` of ``anchor``, the
    origin of the last movable joint passed, in the current frame. A revolute joint moves a
    point at its distance from the joint's axis line per radian: the exact largest distance
    while the points are rigid, else ``distance(anchor, axis) + reach``.
    """
    anchor, reach = np.zeros(3), radius
    for joint in reversed(chain):
        axis = joint.axis
        if joint.type in MOVABLE and _leader(robot, joint)[0] in swept:
            if joint.type == "prismatic":
                yield joint, scale
            elif local is not None:
                yield (
                    joint,
                    float(np.linalg.norm(local - np.outer(local @ axis, axis), axis=1).max()),
                )
            else:
                yield joint, float(np.linalg.norm(anchor - (anchor @ axis) * axis)) + reach
        origin = joint.origin.copy()
        origin[:3, 3] *= scale
        if joint.type in MOVABLE:
            if local is not None:  # the points stop being rigid here
                reach = float(np.linalg.norm(local, axis=1).max())
                local = None
            else:
                reach += float(np.linalg.norm(anchor))
            if joint.type == "prismatic":
                reach += _extent(robot, joint, swept, base) * scale
            anchor = origin[:3, 3].copy()
        elif local is not None:
            local = local @ origin[:3, :3].T + origin[:3, 3]
        else:
            anchor = origin[:3, :3] @ anchor + origin[:3, 3]


def _poses(robot: Robot, base: dict, names: list[str], values: np.ndarray) -> dict:
    """Every movable joint's values for the rows of ``values``, ``{name: (E,) float64}``: the
    free joints ``names`` from ``values``, the other leading joints at ``base``, mimic joints
    following their leaders."""
    count = len(values)
    out = {j.name: np.full(count, base[j.name]) for j in robot.movable}
    for k, name in enumerate(names):
        out[name] = values[:, k]
    return with_mimics(robot, out)  # elementwise on the (E,) arrays


def _motions(joint, values: np.ndarray) -> np.ndarray:
    """(E, 4, 4) motions of one joint at E values (Rodrigues, vectorised)."""
    out = np.zeros((len(values), 4, 4))
    out[:, 3, 3] = 1.0
    if joint.type == "prismatic":
        out[:, 0, 0] = out[:, 1, 1] = out[:, 2, 2] = 1.0
        out[:, :3, 3] = values[:, None] * joint.axis
        return out
    x, y, z = joint.axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    out[:, :3, :3] = (
        np.eye(3)
        + np.sin(values)[:, None, None] * k
        + (1.0 - np.cos(values))[:, None, None] * (k @ k)
    )
    return out


def _chain_transforms(
    chain: list, poses: dict, scale: float, count: int, axes: dict | None = None
) -> np.ndarray:
    """(E, 4, 4) placements of a chain's last link in the root frame, report units, for
    ``count`` poses; with ``axes``, each movable joint's axis line at each pose goes there,
    ``{name: ((E, 3) point on it, report units, (E, 3) unit direction)}``."""
    placed = np.broadcast_to(np.eye(4), (count, 4, 4))
    fixed = np.eye(4)  # origins (and held joints) since the last motion, folded into one matrix
    for joint in chain:
        fixed = fixed @ joint.origin
        if joint.type in MOVABLE:
            placed = placed @ fixed
            if axes is not None:
                axes[joint.name] = (placed[:, :3, 3] * scale, placed[:, :3, :3] @ joint.axis)
            placed = placed @ _motions(joint, poses[joint.name])
            fixed = np.eye(4)
    placed = placed @ fixed
    placed[:, :3, 3] *= scale
    return placed


def _posed(pack, transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A local pack's points placed by each of E transforms: (E, N, 3) points and each piece's
    (E, m, 3) lower and upper corners."""
    points = np.matmul(pack.points, transforms[:, :3, :3].transpose(0, 2, 1))
    points += transforms[:, None, :3, 3]
    starts = pack.starts[:-1]
    lower = np.minimum.reduceat(points, starts, axis=1)
    upper = np.maximum.reduceat(points, starts, axis=1)
    return points, lower, upper


def _spheres_within(pack_a, pack_b, ta, tb, reach: np.ndarray, pad: float) -> np.ndarray:
    """Which of E placements bring the two links' bounding spheres (grown by ``pad``) within
    ``reach`` (the others' pieces are farther apart than that: nothing need be posed)."""
    out = []
    for pack, t in ((pack_a, ta), (pack_b, tb)):
        centre = 0.5 * (pack.points.min(axis=0) + pack.points.max(axis=0))
        radius = float(np.linalg.norm(pack.points - centre, axis=1).max())
        out.append((t[:, :3, :3] @ centre + t[:, :3, 3], radius))
    (pa, ra), (pb, rb) = out
    return np.linalg.norm(pa - pb, axis=1) - ra - rb - pad <= reach


def piece_distances(
    pack_a, pack_b, ta, tb, reach: np.ndarray, pad_a=None, pad_b=None, *, settle: bool = False
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
        Only whether each placement comes within ``reach`` matters: the piece pair whose
        boxes are nearest is measured first, and a placement it brings within reach gets that
        pair's distance (at most ``reach``, not the least) and no more GJK; the others are
        measured in full. The sweep's boxes split or close on this alone (``bench/sweep.py
        --pair`` prints the piece pairs a link pair's boxes measured).

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
    near = _spheres_within(pack_a, pack_b, ta, tb, reach, float(pad_a.max() + pad_b.max()))
    if np.any(near):  # pose only the placements whose links' spheres come within reach
        lowest[near] = _posed_distances(
            pack_a, pack_b, ta[near], tb[near], reach[near], pad_a, pad_b, settle
        )
    return lowest


def _posed_distances(pack_a, pack_b, ta, tb, reach, pad_a, pad_b, settle=False) -> np.ndarray:
    """``piece_distances`` of placements whose links come near: link b's pieces posed in link
    a's frame (distances do not change under the rigid motion of both, and a's pieces then
    serve every placement unmoved), the piece pairs whose boxes come within reach (plus pads)
    measured by GJK."""
    from .geometry import ConvexPack, Status, query_pairs

    e_count = len(ta)
    lowest = np.full(e_count, np.inf)
    rotation = ta[:, :3, :3].transpose(0, 2, 1)
    relative = np.zeros((e_count, 4, 4))
    relative[:, :3, :3] = rotation @ tb[:, :3, :3]
    relative[:, :3, 3] = np.einsum("eij,ej->ei", rotation, tb[:, :3, 3] - ta[:, :3, 3])
    relative[:, 3, 3] = 1.0
    pb, lb, ub = _posed(pack_b, relative)
    la, ua = pack_a.lower, pack_a.upper
    ma, mb = len(pack_a.starts) - 1, len(pack_b.starts) - 1
    gap = np.maximum(
        la[None, :, None, :] - ub[:, None, :, :], lb[:, None, :, :] - ua[None, :, None, :]
    )
    box_gap = np.linalg.norm(np.maximum(gap, 0.0), axis=3)  # (E, ma, mb), a lower bound
    pads = pad_a[:, None] + pad_b[None, :]
    e, i, j = np.nonzero(box_gap - pads[None] <= reach[:, None, None])
    if len(e) == 0:
        return lowest
    na, nb = len(pack_a.points), len(pack_b.points)
    points = np.concatenate([pack_a.points, pb.reshape(-1, 3)])
    starts = np.concatenate(
        [
            pack_a.starts[:-1],
            (na + pack_b.starts[:-1][None, :] + nb * np.arange(e_count)[:, None]).ravel(),
            [na + nb * e_count],
        ]
    )
    ea, eb = len(pack_a.nbrs), len(pack_b.nbrs)
    nbr_starts = np.concatenate(
        [
            pack_a.nbr_starts[:-1],
            (ea + pack_b.nbr_starts[:-1][None, :] + eb * np.arange(e_count)[:, None]).ravel(),
            [ea + eb * e_count],
        ]
    )
    nbrs = np.concatenate(
        [pack_a.nbrs, (na + pack_b.nbrs[None, :] + nb * np.arange(e_count)[:, None]).ravel()]
    )
    lower = np.concatenate([la, lb.reshape(-1, 3)])
    upper = np.concatenate([ua, ub.reshape(-1, 3)])
    pack = ConvexPack(points, starts, nbr_starts, nbrs, lower, upper)
    pairs = np.stack([i, ma + e * mb + j], axis=1)
    pad = pads[i, j]

    def measure(rows):
        res = query_pairs(pack, pairs[rows], tolerance=0.0, depth=False,
                          max_distance=reach[e[rows]] + pad[rows])  # fmt: skip
        found = np.where(res.status == Status.UNDECIDED, np.minimum(res.distance, 0.0),
                         res.distance)  # fmt: skip
        return found - pad[rows]

    rest = np.arange(len(e))
    if settle:  # each placement's nearest boxes first: is it within reach?
        order = np.lexsort((box_gap[e, i, j] - pad, e))
        first = order[np.flatnonzero(np.diff(e[order], prepend=-1))]
        lowest[e[first]] = measure(first)
        rest = rest[lowest[e] > reach[e]]
        lowest[e[first]] = np.where(lowest[e[first]] <= reach[e[first]], lowest[e[first]], np.inf)
    np.minimum.at(lowest, e[rest], measure(rest))
    return lowest


@dataclass(frozen=True)
class _Term:
    """One swept joint between the pair's common ancestor and one of its links."""

    joint: object  # load.robot.Joint
    lead: int  # its leading joint's index among the pair's free joints
    multiplier: float  # |its value's change per unit of the leader's|
    weight: float  # bound on the link's points' speed per unit of it, over the whole sweep


@dataclass(frozen=True)
class _Side:
    """One link of a pair, for the motion bound of a box (``_Pair.box_weights``)."""

    link: str
    terms: tuple[_Term, ...]  # joints from the common ancestor down to the link
    hull: np.ndarray  # (k, 3) a few points, link frame, whose hull grown by ``pad`` holds it
    pad: float


def _side(robot: Robot, chain: list, link: _Link, name: str, names, swept, base, scale):
    """The ``_Side`` of link ``name`` below the common ancestor (``chain``: the joints there)."""
    terms = []
    for joint, weight in _chain_weights(robot, chain, link.radius, link.points, swept, base,
                                        scale):  # fmt: skip
        leader, multiplier = _leader(robot, joint)
        terms.append(_Term(joint, names.index(leader), abs(multiplier), weight))
    return _Side(name, tuple(terms[::-1]), link.hull, link.hull_pad)


def surface_distance(a: _Link, b: _Link, ta: np.ndarray, tb: np.ndarray, reach: float) -> float:
    """The distance between two links' real surfaces placed by ``ta``, ``tb``, exact when at
    most ``reach`` (else a value above it): the triangle pairs whose boxes come within
    ``reach`` (a bounding-volume hierarchy), measured exactly; 0 where surfaces cross."""
    from .geometry.triangles import box_pairs, pair_distances, triangle_boxes

    va = a.vertices @ ta[:3, :3].T + ta[:3, 3]
    vb = b.vertices @ tb[:3, :3].T + tb[:3, 3]
    alo, ahi = triangle_boxes(va, a.faces)
    blo, bhi = triangle_boxes(vb, b.faces)
    pairs = box_pairs(alo, ahi, blo, bhi, reach)
    if len(pairs) == 0:
        return np.inf
    return float(pair_distances(va, a.faces, vb, b.faces, pairs)[0].min())


@dataclass
class _Pair:
    """What one link pair's sweep needs."""

    robot: Robot
    a: str
    b: str
    names: list[str]  # the free joints
    sides: tuple[_Side, _Side]
    base: dict
    scale: float
    tolerance: float
    links: dict  # link -> _Link
    bodies: Sequence[Body]

    def placements(self, values: np.ndarray, axes: dict | None = None):
        """(ta, tb, poses): the links' placements at the rows of ``values`` and every joint's
        values there; each movable joint's axis line goes to ``axes`` when given."""
        poses = _poses(self.robot, self.base, self.names, values)
        count = len(values)
        ta = _chain_transforms(_chain(self.robot, self.a), poses, self.scale, count, axes)
        tb = _chain_transforms(_chain(self.robot, self.b), poses, self.scale, count, axes)
        return ta, tb, poses

    def box_weights(self, ta, tb, axes: dict, half: np.ndarray) -> np.ndarray:
        """(E, n) bounds on how fast a unit change of each free joint moves any point of the
        two links, anywhere in the boxes of half-widths ``half`` about the placements
        ``ta``, ``tb`` (their centres; ``axes`` from ``placements``).

        A revolute joint ``k`` moves a point ``p`` at ``dist(p, axis_k)`` per radian. At the
        centre, ``dist(p, axis_k)`` is at most the largest distance of the link's few hull
        points ``_Side.hull`` plus their ``pad`` (the distance to a line is convex, so a hull's
        largest is at a vertex); within the box ``p`` moves relative to joint ``k``'s frame
        only by the joints ``j`` below ``k``, by at most ``sum_j h_j r_j``, where ``r_j`` is
        this bound for ``j`` (computed first, from the link up). So ``r_k = min(w_k,
        max dist(hull, axis_k) + pad + sum_j h_j r_j)``, with ``w_k`` the bound over the whole
        sweep (``motion_weights``); a slide moves points at one unit per unit. The links'
        distance then changes by at most ``sum_k h_k r_k`` within the box.
        """
        out = np.zeros(half.shape)
        for side, placed in zip(self.sides, (ta, tb), strict=True):
            hull = np.matmul(side.hull, placed[:, :3, :3].transpose(0, 2, 1))
            hull += placed[:, None, :3, 3]  # (E, k, 3)
            below = np.zeros(len(half))
            for term in reversed(side.terms):  # from the link up
                if term.joint.type == "prismatic":
                    r = np.full(len(half), term.weight)
                else:
                    point, direction = axes[term.joint.name]
                    d = hull - point[:, None, :]
                    along = np.einsum("ekj,ej->ek", d, direction)
                    off = d - along[:, :, None] * direction[:, None, :]
                    lever = np.sqrt(np.einsum("ekj,ekj->ek", off, off).max(axis=1))
                    r = np.minimum(term.weight, lever + side.pad + below)
                out[:, term.lead] += term.multiplier * r
                below = below + term.multiplier * half[:, term.lead] * r
        return out

    def distances(self, ta: np.ndarray, tb: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """Lower bounds on the distance between the two links' surfaces at placements ``ta``,
        ``tb``: from the coarse pieces (``piece_distances``), and where those come within
        ``reach`` and the reach is below ``FINE_REACH`` of the smaller link's size, the real
        meshes' exact distance (``surface_distance``: its cost grows with the triangle pairs
        within reach, so it waits for boxes small enough that it can close them)."""
        a, b = self.links[self.a], self.links[self.b]
        lowest = piece_distances(a.pack, b.pack, ta, tb, reach, a.pad, b.pad, settle=True)
        fine = FINE_REACH * min(np.ptp(a.points, axis=0).max(), np.ptp(b.points, axis=0).max())
        for e in np.flatnonzero((lowest <= reach) & (reach <= fine)):
            lowest[e] = surface_distance(a, b, ta[e], tb[e], float(reach[e]))
        return lowest

    def verdict(self, ta: np.ndarray, tb: np.ndarray, *, surfaces_apart: bool = False) -> str:
        """The real meshes' worst status at one placement of the two links."""
        from .results import Verdict
        from .verify.pair import verify_pair

        worst = Verdict.CLEAR
        for i, offset_i in self.links[self.a].parts:
            mesh_a = self.bodies[i].mesh.copy().apply_transform(ta @ offset_i)
            for j, offset_j in self.links[self.b].parts:
                mesh_b = self.bodies[j].mesh.copy().apply_transform(tb @ offset_j)
                status = verify_pair(
                    mesh_a,
                    mesh_b,
                    tolerance=self.tolerance,
                    clearance=None,
                    surfaces_apart=surfaces_apart,
                ).status
                if status == Verdict.INTERFERENCE:
                    return str(status)
                if status == Verdict.TOUCHING:
                    worst = Verdict.TOUCHING
        return str(worst)


def sweep_pair(pair: _Pair, lower: np.ndarray, upper: np.ndarray, resolution: float) -> PairSweep:
    """Classify one link pair over the box ``lower..upper`` of its free joints.

    Boxes of joint values are evaluated at their centre ``c`` with half-widths ``h``: the
    pieces' distance there (or, for a box small enough, the real triangles', see
    ``_Pair.distances``) bounds the links' surface distance from below, and no point moves by
    more than ``M = sum_k r_k h_k`` (``_Pair.box_weights``: each joint's lever arm bounded at
    the box's centre pose) within the box, so a box whose centre distance exceeds
    ``M + tolerance`` is certified free of contact. Other boxes are halved along the joint that
    contributes most to ``M``, down to ``resolution``. Centres where pieces overlap are
    re-checked on the real meshes, nearest first: one that interferes or touches is the witness
    of ``sometimes``; after ``DESCENT_AFTER`` boxes, a descent from the nearest centres looks
    for one (``_descent_witness``). When every box is certified, the surfaces never come within
    the tolerance, so whether one link is buried in the other cannot change over the sweep: one
    exact check at the centre decides ``never`` (or ``always``, buried throughout).
    """
    if len(lower) == 0:  # nothing moves one link relative to the other
        ta, tb, _ = pair.placements(np.zeros((1, 0)))
        verdict = pair.verdict(ta[0], tb[0])
        if verdict in ("interference", "touching"):
            return _result(pair, ALWAYS, 1, {}, verdict)
        return _result(pair, NEVER, 1)
    found = _sampled_witness(pair, lower, upper)
    if found is not None:
        return found
    lo, hi = lower[None, :].copy(), upper[None, :].copy()
    evaluated, checks, unresolved = SAMPLES, 0, False
    nearest = _Nearest(DESCENT_STARTS)
    while len(lo):
        if nearest is not None and evaluated >= DESCENT_AFTER:
            found = _descent_witness(pair, lower, upper, nearest.values, evaluated)
            if found is not None:
                return found
            nearest = None
        blo, bhi, lo, hi = lo[:BATCH], hi[:BATCH], lo[BATCH:], hi[BATCH:]
        centre, half = 0.5 * (blo + bhi), 0.5 * (bhi - blo)
        axes: dict = {}
        ta, tb, poses = pair.placements(centre, axes)
        w = pair.box_weights(ta, tb, axes, half)
        bound = np.sum(half * w, axis=1) + pair.tolerance
        lowest = pair.distances(ta, tb, bound)
        evaluated += len(centre)
        if nearest is not None:
            nearest.add(lowest, centre)
        for e in np.argsort(lowest, kind="stable"):
            if lowest[e] > pair.tolerance or checks >= MAX_WITNESS_CHECKS:
                break
            checks += 1
            status = pair.verdict(ta[e], tb[e])
            if status in ("interference", "touching"):
                witness = {n: float(poses[n][e]) for n in pair.names}
                return _result(pair, SOMETIMES, evaluated, witness, status)
        open_ = lowest <= bound
        if not np.any(open_):
            continue
        blo, bhi, half, w = blo[open_], bhi[open_], half[open_], w[open_]
        splittable = np.any(2.0 * half > resolution, axis=1)
        for e in np.flatnonzero(~splittable)[: max(0, MAX_WITNESS_CHECKS - checks) // 2]:
            unresolved = True  # at the resolution: its corners may still collide
            checks += 2
            found = _witness(pair, np.stack([blo[e], bhi[e]]), evaluated)
            if found is not None:
                return found
        unresolved |= bool(np.any(~splittable))
        new_lo, new_hi = _halve(blo[splittable], bhi[splittable], w[splittable])
        lo, hi = np.concatenate([lo, new_lo]), np.concatenate([hi, new_hi])
        if evaluated + len(lo) > MAX_BOXES:
            return _result(pair, UNDECIDED, evaluated)
    if unresolved:
        return _result(pair, UNDECIDED, evaluated)
    ta, tb, _ = pair.placements(0.5 * (lower + upper)[None, :])
    buried = pair.verdict(ta[0], tb[0], surfaces_apart=True) == "interference"
    return _result(pair, ALWAYS if buried else NEVER, evaluated)


def _halve(lo: np.ndarray, hi: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each box ``lo..hi`` cut in two across the joint contributing most to its motion bound
    (``w``: (E, n) each box's bound per unit of each joint)."""
    axis = np.argmax(0.5 * (hi - lo) * w, axis=1)
    rows = np.arange(len(axis))
    mid = 0.5 * (lo[rows, axis] + hi[rows, axis])
    left_hi, right_lo = hi.copy(), lo.copy()
    left_hi[rows, axis], right_lo[rows, axis] = mid, mid
    return np.concatenate([lo, right_lo]), np.concatenate([left_hi, hi])


class _Nearest:
    """The ``count`` box centres whose links came nearest so far (ties: the earlier)."""

    def __init__(self, count: int):
        self.count, self.lowest, self.values = count, np.empty(0), None

    def add(self, lowest: np.ndarray, values: np.ndarray) -> None:
        both = np.concatenate([self.lowest, lowest])
        rows = values if self.values is None else np.concatenate([self.values, values])
        keep = np.argsort(both, kind="stable")[: self.count]
        self.lowest, self.values = both[keep], rows[keep]


def _descent_witness(pair: _Pair, lower, upper, starts, boxes: int) -> PairSweep | None:
    """A witness near the box centres where the links came nearest (``starts``): each is
    moved, ``DESCENT_STEPS`` times, to the nearest of ``DESCENT_TRIES`` perturbations of it
    (fixed seed; each joint's step in proportion to its range, halved when none comes nearer)
    by the coarse pieces' signed distance; the final poses whose pieces overlap are
    re-checked on the real meshes, nearest first. A pair colliding only in a narrow window
    of many joints is found in a few thousand poses instead of by splitting boxes down to it.
    """
    if starts is None or len(starts) == 0:
        return None
    rng = np.random.default_rng(1)
    a, b = pair.links[pair.a], pair.links[pair.b]

    def measure(values, reach: float):
        ta, tb, _ = pair.placements(values)
        return piece_distances(a.pack, b.pack, ta, tb, np.full(len(values), reach), a.pad, b.pad)

    current = starts.copy()
    scores = measure(current, np.inf)
    reach = max(float(scores.max()), 0.0) + pair.tolerance  # nothing beyond the starts matters
    step = np.broadcast_to(0.125 * (upper - lower), current.shape).copy()
    for _ in range(DESCENT_STEPS):
        noise = rng.standard_normal((len(current), DESCENT_TRIES, len(lower)))
        tries = np.clip(current[:, None, :] + step[:, None, :] * noise, lower, upper)
        flat = measure(tries.reshape(-1, len(lower)), reach).reshape(len(current), DESCENT_TRIES)
        best = np.argmin(flat, axis=1)
        better = flat[np.arange(len(current)), best] < scores
        current[better] = tries[better, best[better]]
        scores[better] = flat[better, best[better]]
        step[~better] *= 0.5
    order = np.argsort(scores, kind="stable")
    order = order[scores[order] <= pair.tolerance][:SAMPLE_CHECKS]
    return _witness(pair, current[order], boxes)


def _sampled_witness(pair: _Pair, lower: np.ndarray, upper: np.ndarray) -> PairSweep | None:
    """A witness among ``SAMPLES`` poses drawn with a fixed seed (most pairs that collide do so
    over a wide region, found here before any box is split), else None."""
    rng = np.random.default_rng(0)
    values = lower + (upper - lower) * rng.random((SAMPLES, len(lower)))
    ta, tb, _ = pair.placements(values)
    lowest = pair.distances(ta, tb, np.full(SAMPLES, pair.tolerance))
    order = np.argsort(lowest, kind="stable")[:SAMPLE_CHECKS]
    return _witness(pair, values[order[lowest[order] <= pair.tolerance]], SAMPLES)


def _witness(pair: _Pair, values: np.ndarray, boxes: int) -> PairSweep | None:
    """The first of ``values`` (free joints' values, (k, n)) where the real meshes collide."""
    if len(values) == 0:
        return None
    ta, tb, poses = pair.placements(values)
    for e in range(len(values)):
        status = pair.verdict(ta[e], tb[e])
        if status in ("interference", "touching"):
            witness = {n: float(poses[n][e]) for n in pair.names}
            return _result(pair, SOMETIMES, boxes, witness, status)
    return None


def _result(pair: _Pair, status: str, boxes: int, witness=None, verdict=None) -> PairSweep:
    return PairSweep(pair.a, pair.b, status, tuple(pair.names), witness, verdict, boxes)


def sweep_mechanism(
    mech: Mechanism,
    bodies: Sequence[Body],
    pieces: dict[int, list[np.ndarray]],
    motion,
    *,
    tolerance: float | None = None,
) -> tuple[PairSweep, ...]:
    """Classify every pair of a robot's links over the swept joints' ranges (``sweep_pair``).

    Parameters
    ----------
    mech : Mechanism
    bodies : sequence of Body
        The run's parts, placed at ``motion.pose``.
    pieces : dict of int -> list of (n_i, 3) float64
        Convex pieces of each of the robot's parts, world coordinates at that pose, covering
        every triangle (``decompose.decompose_bodies``).
    motion : motion.Motion
        The pose (held joints stay there), the joints swept (``()``: every movable one) and the
        resolution.
    tolerance : float, optional
        Touching tolerance, report units; default each pair's own (``settings.pair_tolerances``).

    Returns
    -------
    tuple of PairSweep
        One per pair of links with collision geometry, sorted by link names.
    """
    from .load.robot import joint_values
    from .settings import pair_tolerances, part_sizes
    from .units import scale as unit_scale

    robot = mech.robot
    base = joint_values(robot, motion.pose)
    swept = _swept(robot, motion.sweep)
    scale = unit_scale(mech.units, bodies[mech.parts[next(iter(mech.parts))][0]].units)
    links = _links(robot, mech, bodies, pieces, base, scale)
    radius = {name: link.radius for name, link in links.items()}
    points = {name: link.points for name, link in links.items()}
    names = sorted(links)
    lower = np.array([links[n].points.min(axis=0) for n in names])
    upper = np.array([links[n].points.max(axis=0) for n in names])
    diagonal, _ = part_sizes(lower, upper)
    magnitude = np.full(len(names), max(radius.values()) + _reach(robot, swept, base) * scale)
    out = []
    for x, a in enumerate(names):
        for y in range(x + 1, len(names)):
            b = names[y]
            tol = tolerance
            if tol is None:
                tol = float(pair_tolerances(diagonal, magnitude, np.array([[x, y]]))[0])
            weights = motion_weights(robot, (a, b), radius, swept, base, scale, points)
            if not weights and not mech.is_urdf:
                continue  # nothing moves them: the check judged them at the pose
            free = sorted(weights)
            sides = _sides(robot, (a, b), links, free, swept, base, scale)
            pair = _Pair(robot, a, b, free, sides, base, scale, tol, links, bodies)
            lo, hi = _ranges(robot, free)
            swept_pair = sweep_pair(pair, lo, hi, motion.resolution)
            is_adjacent = frozenset((a, b)) in mech.adjacent
            out.append(dataclasses.replace(swept_pair, is_adjacent=is_adjacent))
    return tuple(out)


def _sides(robot, pair, links, names, swept, base, scale) -> tuple[_Side, _Side]:
    """Both links' ``_Side``: the joints from their common ancestor down to each."""
    return tuple(
        _side(robot, chain, links[name], name, names, swept, base, scale)
        for chain, name in zip(_below_common(robot, pair), pair, strict=True)
    )


def _swept(robot: Robot, named) -> set[str]:
    """The joints of ``robot`` swept: every movable one when ``named`` is empty, else those of
    ``named`` it has (``check_swept`` refused names no mechanism of the run has)."""
    from .errors import ConfigError

    if not named:
        return {j.name for j in robot.movable}
    out = set()
    for name in named:
        joint = next((j for j in robot.joints if j.name == name), None)
        if joint is None:
            continue
        if joint not in robot.movable:
            raise ConfigError(robot.path, f"--sweep {name}: not a movable joint that leads")
        out.add(name)
    return out


def check_swept(found: Sequence[Mechanism], named) -> None:
    """Refuse a joint of ``--sweep-joints`` that no mechanism of the run has (``ConfigError``
    from the first robot, listing its joints)."""
    for name in named or ():
        if found and not any(name in {j.name for j in m.robot.joints} for m in found):
            found[0].robot.joint(name)  # raises, naming the robot's movable joints


def _ranges(robot: Robot, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's range; a continuous joint's is one turn, [-pi, pi]."""
    lo, hi = [], []
    for name in names:
        joint = robot.joint(name)
        lo.append(joint.lower if np.isfinite(joint.lower) else -np.pi)
        hi.append(joint.upper if np.isfinite(joint.upper) else np.pi)
    return np.array(lo), np.array(hi)


def _reach(robot: Robot, swept: set[str], base: dict) -> float:
    """A bound on how far any joint frame gets from the root, metres."""
    total = 0.0
    for joint in robot.joints:
        total += float(np.linalg.norm(joint.origin[:3, 3]))
        if joint.type == "prismatic":
            total += _extent(robot, joint, swept, base)
    return total


def _links(robot, mech, bodies, pieces, base, scale) -> dict[str, _Link]:
    """Each link's pieces in its own frame and its parts' offsets from it."""
    from .geometry import pack_convex
    from .load.robot import link_transforms

    placed = link_transforms(robot, base)
    out = {}
    for link, ks in sorted(mech.parts.items()):
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
        out[link] = _Link(pack_convex(coarse, is_hull=True), radius, parts, pad, points, hull,
                          float(hull_pad), np.vstack(vertices), np.vstack(faces))  # fmt: skip
    return out


@dataclass(frozen=True)
class RobotSweep:
    """One robot's sweep: its URDF (or configuration file), its name, every link pair's
    ``PairSweep``, and whether it is a URDF robot (the SRDF describes one)."""

    path: str
    name: str
    pairs: tuple[PairSweep, ...]
    is_urdf: bool = True

    def to_dict(self) -> dict:
        """The robot's sweep as the JSON report lists it: counts by status, every pair."""
        return {
            "robot": self.path,
            "name": self.name,
            "counts": {s: sum(p.status == s for p in self.pairs) for s in STATUSES},
            "pairs": [p.to_dict() for p in self.pairs],
        }


def summary(robot: RobotSweep) -> str:
    """One line: how many link pairs of a robot are never, sometimes, always in contact."""
    counts = {s: sum(p.status == s for p in robot.pairs) for s in STATUSES}
    shown = ", ".join(f"{n} {s}" for s, n in counts.items() if n or s != ALWAYS)
    adjacent = sum(p.is_adjacent for p in robot.pairs)
    return f"{robot.path}: {len(robot.pairs)} link pairs ({adjacent} adjacent): {shown}"


def with_sweeps(result, bodies: Sequence[Body], settings, *, executor=None):
    """``result`` with the sweep of every robot among ``bodies`` when ``settings.motion.sweep``
    is set (``CheckResult.sweeps``)."""
    if settings.motion.sweep is None:
        return result
    sweeps = sweep_bodies(bodies, settings, executor=executor)
    return dataclasses.replace(result, sweeps=_approved(sweeps, bodies, settings.approvals))


def _approved(sweeps, bodies: Sequence[Body], approvals) -> tuple[RobotSweep, ...]:
    """The sweeps with each ``[[joint]]`` mechanism's pair given the reason of the approval
    rule its two parts (links named by the parts' full names) match, if any."""
    from .config import approval_reason

    names = {b.name: (b.name, b.relative_name) for b in bodies}
    out = []
    for robot in sweeps:
        if not robot.is_urdf:
            pairs = tuple(
                dataclasses.replace(
                    p, approval_reason=approval_reason(approvals, names[p.a], names[p.b])
                )
                for p in robot.pairs
            )
            robot = dataclasses.replace(robot, pairs=pairs)
        out.append(robot)
    return tuple(out)


def sweep_bodies(bodies: Sequence[Body], settings, *, executor=None) -> tuple[RobotSweep, ...]:
    """``sweep_mechanism`` of every robot among ``bodies``."""
    from .decompose import decompose_bodies

    out: list[RobotSweep] = []
    found = mechanisms(bodies, settings.motion.joints)
    check_swept(found, settings.motion.sweep)
    for mech in found:
        ks = sorted(k for ks in mech.parts.values() for k in ks)
        piece_lists = decompose_bodies(
            [bodies[k] for k in ks],
            threshold=settings.threshold,
            cache_dir=settings.cache_dir,
            jobs=settings.jobs,
            executor=executor,
            # No time limit: a CoACD time-out would swap a link's pieces for its hull, and the
            # sweep's classes (the SRDF) would then depend on how the run went.
            time_limit=None,
        )
        pieces = dict(zip(ks, piece_lists, strict=True))
        pairs = sweep_mechanism(mech, bodies, pieces, settings.motion, tolerance=settings.tolerance)
        out.append(RobotSweep(mech.robot.path, mech.robot.name, pairs, mech.is_urdf))
    return tuple(out)
