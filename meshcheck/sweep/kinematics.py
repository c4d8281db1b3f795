"""The sweep's kinematics: joint ranges, and bounds on how fast a joint moves a link's points
(the motion bound every certified box rests on). The placements themselves, at one pose or at
many, are ``load.robot``'s.

Lengths are report units: a robot's own lengths (metres for a URDF) times ``scale``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..geometry import farthest_from_lines
from ..load.robot import MOVABLE, Joint, Robot


def joint_ranges(robot: Robot, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's range; a continuous joint's is one turn, [-pi, pi]."""
    lo, hi = [], []
    for name in names:
        joint = robot.joint(name)
        lo.append(joint.lower if np.isfinite(joint.lower) else -np.pi)
        hi.append(joint.upper if np.isfinite(joint.upper) else np.pi)
    return np.array(lo), np.array(hi)


def slide_extent(robot: Robot, joint: Joint, swept: set[str], base: dict[str, float]) -> float:
    """Largest |value| a prismatic joint takes in the sweep, the robot's length unit."""
    name, multiplier = robot.leader(joint)
    offset = joint.mimic[2] if joint.mimic is not None else 0.0
    if name not in swept:
        return abs(base[joint.name])
    lead = next(j for j in robot.joints if j.name == name)
    return max(abs(multiplier * lead.lower + offset), abs(multiplier * lead.upper + offset))


def frame_reach(robot: Robot, swept: set[str], base: dict) -> float:
    """A bound on how far any joint frame gets from the root, the robot's length unit."""
    total = 0.0
    for joint in robot.joints:
        total += float(np.linalg.norm(joint.origin[:3, 3]))
        if joint.type == "prismatic":
            total += slide_extent(robot, joint, swept, base)
    return total


def joints_below_common(robot: Robot, pair: tuple[str, str]) -> tuple[list, list]:
    """The joints from the two links' common ancestor down to each link of ``pair``: only
    they move one link relative to the other."""
    a_chain, b_chain = robot.chain(pair[0]), robot.chain(pair[1])
    common = 0
    while common < min(len(a_chain), len(b_chain)) and a_chain[common] is b_chain[common]:
        common += 1
    return a_chain[common:], b_chain[common:]


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
        Every movable joint's value where it does not move (``load.robot.joint_values``).
    scale : float
        Report units per unit of the robot's lengths.
    points : dict of str -> (n, 3) float64, optional
        Each link's geometry (hull vertices) in its own frame, report units: the joints that
        turn a link with only fixed joints between get the exact largest distance of its points
        from their axis line, and the joints above a bound from it (``chain_weights``).
    """
    out: dict[str, float] = {}
    for chain, link in zip(joints_below_common(robot, pair), pair, strict=True):
        local = None if points is None else points.get(link)
        for joint, weight in chain_weights(robot, chain, radius[link], local, swept, base, scale):
            name, multiplier = robot.leader(joint)
            out[name] = out.get(name, 0.0) + abs(multiplier) * weight
    return out


def chain_weights(
    robot: Robot,
    chain: list[Joint],
    radius: float,
    local: np.ndarray | None,
    swept: set[str],
    base: dict[str, float],
    scale: float,
    margin: float = 0.0,
) -> Iterator[tuple[Joint, float]]:
    """(joint, bound on the speed of the link's points per unit of it) up one chain.

    Walking up from the link, the points are either rigid in the current frame (``local``,
    report units: only fixed joints passed; the link's geometry lies within ``margin`` of their
    hull) or known to lie within ``reach`` of ``anchor``, the origin of the last movable joint
    passed, in the current frame. A revolute joint moves a point at its distance from the
    joint's axis line per radian: the largest distance (exact for ``margin`` 0) while the
    points are rigid, else ``distance(anchor, axis) + reach``.
    """
    anchor, reach = np.zeros(3), radius
    for joint in reversed(chain):
        axis = joint.axis
        if joint.type in MOVABLE and robot.leader(joint)[0] in swept:
            if joint.type == "prismatic":
                yield joint, scale
            elif local is not None:
                lever = np.linalg.norm(local - np.outer(local @ axis, axis), axis=1).max()
                yield joint, float(lever) + margin
            else:
                yield joint, float(np.linalg.norm(anchor - (anchor @ axis) * axis)) + reach
        origin = joint.origin.copy()
        origin[:3, 3] *= scale
        if joint.type in MOVABLE:
            if local is not None:  # the points stop being rigid here
                reach = float(np.linalg.norm(local, axis=1).max()) + margin
                local = None
            else:
                reach += float(np.linalg.norm(anchor))
            if joint.type == "prismatic":
                reach += slide_extent(robot, joint, swept, base) * scale
            anchor = origin[:3, 3].copy()
        elif local is not None:
            local = local @ origin[:3, :3].T + origin[:3, 3]
        else:
            anchor = origin[:3, :3] @ anchor + origin[:3, 3]


# --------------------------------------------------------------------------------------------
# The motion bound of a box of joint values


@dataclass(frozen=True)
class JointTerm:
    """One swept joint between a link pair's common ancestor and one of its links.

    Attributes
    ----------
    joint : Joint
    lead : int
        Its leading joint's index among the pair's free joints.
    multiplier : float
        |its value's change per unit of the leader's|.
    weight : float
        Bound on the link's points' speed per unit of it, over the whole sweep.
    """

    joint: Joint
    lead: int
    multiplier: float
    weight: float


@dataclass(frozen=True)
class LinkSide:
    """One link of a pair, for the motion bound of a box (``box_weights``).

    Attributes
    ----------
    link : str
    terms : tuple of JointTerm
        The swept joints from the common ancestor down to the link.
    hull : (k, 3) float64
        A few points, link frame, whose hull grown by ``pad`` holds the link's geometry.
    pad : float
    """

    link: str
    terms: tuple[JointTerm, ...]
    hull: np.ndarray
    pad: float


def link_sides(
    robot: Robot,
    pair: tuple[str, str],
    links: dict,
    free: list[str],
    swept: set[str],
    base: dict[str, float],
    scale: float,
) -> tuple[LinkSide, LinkSide]:
    """Both links' ``LinkSide``: the swept joints from their common ancestor down to each, with
    the bound on the link's speed per unit of each over the whole sweep (``chain_weights``).

    Parameters
    ----------
    links : dict of str -> sweep.distances.LinkGeometry
    free : list of str
        The pair's free (leading, swept) joints, in the order of the box's axes.
    """
    sides = []
    for chain, name in zip(joints_below_common(robot, pair), pair, strict=True):
        link = links[name]
        terms = []
        for joint, weight in chain_weights(
            robot, chain, link.radius, link.points, swept, base, scale, link.points_pad
        ):
            leader, multiplier = robot.leader(joint)
            terms.append(JointTerm(joint, free.index(leader), abs(multiplier), weight))
        sides.append(LinkSide(name, tuple(terms[::-1]), link.hull, link.hull_pad))
    return sides[0], sides[1]


def box_weights(
    sides: tuple[LinkSide, LinkSide], ta: np.ndarray, tb: np.ndarray, axes: dict, half: np.ndarray
) -> np.ndarray:
    """(E, n) bounds on how fast a unit change of each free joint moves any point of the two
    links, anywhere in the boxes of half-widths ``half`` about the placements ``ta``, ``tb``
    (their centres; ``axes`` from ``load.robot.chain_transforms``).

    A revolute joint ``k`` moves a point ``p`` at ``dist(p, axis_k)`` per radian. At the
    centre, ``dist(p, axis_k)`` is at most the largest distance of the link's few hull
    points ``LinkSide.hull`` plus their ``pad`` (the distance to a line is convex, so a hull's
    largest is at a vertex); within the box ``p`` moves relative to joint ``k``'s frame
    only by the joints ``j`` below ``k``, by at most ``sum_j h_j r_j``, where ``r_j`` is
    this bound for ``j`` (computed first, from the link up). So ``r_k = min(w_k,
    max dist(hull, axis_k) + pad + sum_j h_j r_j)``, with ``w_k`` the bound over the whole
    sweep (``motion_weights``); a slide moves points at one unit per unit. The links'
    distance then changes by at most ``sum_k h_k r_k`` within the box.
    """
    return combined_weights(sides, joint_rates(sides, ta, tb, axes, half), half.shape)


def joint_rates(
    sides: tuple[LinkSide, LinkSide], ta: np.ndarray, tb: np.ndarray, axes: dict, half: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each side's ``r`` of every term of ``LinkSide.terms`` (``box_weights``): (E,) bounds,
    over the whole box, on the speed of the link's points per unit of the term's joint; for a
    revolute joint, on their distance from its axis."""
    out = []
    for side, placed in zip(sides, (ta, tb), strict=True):
        turning = [t.joint.name for t in side.terms if t.joint.type != "prismatic"]
        levers = {}
        if turning:
            origins = np.stack([axes[name][0] for name in turning], axis=1)
            directions = np.stack([axes[name][1] for name in turning], axis=1)
            found = farthest_from_lines(side.hull, placed, origins, directions)
            levers = {name: found[:, k] for k, name in enumerate(turning)}
        below = np.zeros(len(half))
        rates: list[np.ndarray] = [np.empty(0)] * len(side.terms)
        for k in range(len(side.terms) - 1, -1, -1):  # from the link up
            term = side.terms[k]
            if term.joint.type == "prismatic":
                r = np.full(len(half), term.weight)
            else:
                r = np.minimum(term.weight, levers[term.joint.name] + side.pad + below)
            rates[k] = r
            below = below + term.multiplier * half[:, term.lead] * r
        out.append(rates)
    return out[0], out[1]


def combined_weights(sides, rates, shape) -> np.ndarray:
    """(E, n) both links' first-order bounds per unit of each free joint (``box_weights``)."""
    out = np.zeros(shape)
    for side, side_rates in zip(sides, rates, strict=True):
        for k in range(len(side.terms) - 1, -1, -1):
            term = side.terms[k]
            out[:, term.lead] += term.multiplier * side_rates[k]
    return out


def side_bounds(side: LinkSide, rates: list[np.ndarray], shape) -> tuple[np.ndarray, np.ndarray]:
    """(E, n) first- and second-order bounds on one link's motion per free joint in a box.

    ``first[:, i]`` bounds ``|dp/dq_i|`` and ``second[:, i]`` bounds ``|d2p/dq_i2|`` for
    every point ``p`` of the link anywhere in the box (``rates`` from ``joint_rates``).

    With ``w_j`` the unit axis of revolute joint ``j`` and ``o_j`` a point on it,
    ``dp/dtheta_j = w_j x (p - o_j)``, of length ``dist(p, axis_j) <= r_j``. For two revolute
    joints ``j`` above ``k`` (nearer the root), turning ``j`` turns axis ``k`` and ``p`` alike,
    so ``d2p/dtheta_j dtheta_k = w_j x (w_k x (p - o_k))``, of length at most ``r_k``; the
    same holds for ``j = k``. A slide ``s`` below a revolute ``j`` turns with it:
    ``d2p/dtheta_j ds = w_j x u_s``, at most the slide's rate; a slide above a revolute
    joint moves its axis and ``p`` alike (0), and two slides commute (0). A free joint leading
    several of the chain's joints (mimic joints, multipliers ``m``) sums
    ``|m_j m_k| * bound(j, k)`` over their pairs.
    """
    first, second = np.zeros(shape), np.zeros(shape)
    terms = side.terms
    for k, term in enumerate(terms):
        first[:, term.lead] += term.multiplier * rates[k]
        for j in range(k + 1):  # j at or above k: terms run from the common ancestor down
            other = terms[j]
            if other.lead != term.lead:
                continue
            revolute = (term.joint.type != "prismatic", other.joint.type != "prismatic")
            if revolute == (True, True):
                bound = rates[k]
            elif revolute == (False, True):  # a slide k below revolute j
                bound = rates[k]
            else:
                continue
            factor = term.multiplier * other.multiplier * (1.0 if j == k else 2.0)
            second[:, term.lead] += factor * bound
    return first, second
