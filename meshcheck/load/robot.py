"""Robots: a tree of links joined by joints, its poses, and which parts are its links.

One model serves every mechanism of a run: a URDF robot (``load.urdf`` parses it, metres), the
mechanism the configuration's ``[[joint]]`` tables make of mesh parts (``load.joints``, report
units), and the sweep, which poses both (``meshcheck.sweep``). A pose gives each movable joint a
value (``joint_values``); each link's placement is the product of the joint origins and motions
from the root down to it (``link_transforms``; ``chain_transforms`` at many poses at once).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..errors import ConfigError
from ..geometry.chains import SLIDE, TURN, chain_placements
from ..results import RobotPose

if TYPE_CHECKING:
    from .srdf import Srdf

#: Joint types with a motion, and the ones held at their zero placement.
MOVABLE = ("revolute", "continuous", "prismatic")
HELD = ("fixed", "floating", "planar")
ROTARY = ("revolute", "continuous")
#: Joint values may pass a limit by this much (radians or metres) and still be within it: limits
#: written as 2.9671 against a pose of 170deg (2.96706) are the same to the file's digits.
LIMIT_SLACK = 1e-6


@dataclass(frozen=True)
class Joint:
    """One joint of a robot.

    Attributes
    ----------
    name, type, parent, child : str
    origin : (4, 4) float64
        Child frame at zero motion, in the parent link's frame, the robot's length unit.
    axis : (3,) float64
        Unit axis in the joint frame (rotation axis, or slide direction).
    lower, upper : float
        Limits, radians or the robot's length unit; -inf/inf for continuous (and held) joints.
    mimic : (str, float, float) or None
        ``(leader, multiplier, offset)``: value = multiplier * leader's value + offset.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float = -math.inf
    upper: float = math.inf
    mimic: tuple[str, float, float] | None = None

    def motion(self, value: float) -> np.ndarray:
        """The joint's motion at ``value``, a (4, 4) transform in the joint frame."""
        out = np.eye(4)
        if self.type in ROTARY:
            out[:3, :3] = rotation(self.axis, value)
        elif self.type == "prismatic":
            out[:3, 3] = self.axis * value
        return out


@dataclass(frozen=True)
class Collision:
    """One collision element of a link (a link's elements together are one part of the run).

    Attributes
    ----------
    link : str
    index : int
        Its position among the link's collision elements.
    origin : (4, 4) float64
        Geometry frame in the link frame, the robot's length unit.
    shape : tuple
        ``("mesh", filename, (3,) scale)``, ``("box", (3,) size)``, ``("cylinder", radius,
        length)`` or ``("sphere", radius)`` for a URDF; ``("part", name)`` for a mesh part of a
        ``[[joint]]`` mechanism.
    name : str or None
        The element's ``name`` attribute, when it has one.
    """

    link: str
    index: int
    origin: np.ndarray
    shape: tuple
    name: str | None = None


@dataclass(frozen=True)
class Robot:
    """A kinematic tree and its collision geometry.

    Attributes
    ----------
    path : str
        The URDF (or the configuration file of ``[[joint]]`` tables), for messages.
    name : str
    root : str
        The link no joint moves.
    links : tuple of str
        In file order.
    joints : tuple of Joint
        Parents before children (each joint's parent link is placed before it).
    collisions : tuple of Collision
    """

    path: str
    name: str
    root: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]
    collisions: tuple[Collision, ...]

    def joint(self, name: str) -> Joint:
        """The joint named ``name``; a ``ConfigError`` naming the robot when there is none."""
        for joint in self.joints:
            if joint.name == name:
                return joint
        movable = [j.name for j in self.joints if j.type in MOVABLE and j.mimic is None]
        shown = ", ".join(movable[:6]) + (" ..." if len(movable) > 6 else "")
        raise ConfigError(self.path, f"no joint named {name!r} (movable joints: {shown})")

    @property
    def movable(self) -> tuple[Joint, ...]:
        """Joints a pose sets: movable and not mimicking another."""
        return tuple(j for j in self.joints if j.type in MOVABLE and j.mimic is None)

    @functools.cached_property
    def _by_child(self) -> dict[str, Joint]:
        return {j.child: j for j in self.joints}

    @functools.cached_property
    def _by_name(self) -> dict[str, Joint]:
        return {j.name: j for j in self.joints}

    def chain(self, link: str) -> list[Joint]:
        """The joints from the root down to ``link``."""
        by_child = self._by_child
        out = []
        while link in by_child:
            out.append(by_child[link])
            link = by_child[link].parent
        return out[::-1]

    def leader(self, joint: Joint) -> tuple[str, float]:
        """(leading joint's name, multiplier): ``joint``'s mimic chain followed to the joint
        that leads it (``(joint.name, 1.0)`` for a joint that mimics none)."""
        by_name = self._by_name
        multiplier = 1.0
        while joint.mimic is not None:
            multiplier *= joint.mimic[1]
            joint = by_name[joint.mimic[0]]
        return joint.name, multiplier


@dataclass(frozen=True)
class Mechanism:
    """One robot of the run (a URDF, or the configuration's ``[[joint]]`` tables) and its links'
    parts.

    Attributes
    ----------
    robot : Robot
    parts : dict of str -> list of int
        Each link's parts, as indices into the run's bodies.
    units : str
        The unit of the robot's lengths: metres for a URDF, the report unit for ``[[joint]]``.
    adjacent : set of frozenset of str
        Link pairs joined by a joint (``adjacent_links`` for a URDF; each ``[[joint]]``'s parent
        parts with its child parts).
    is_urdf : bool
        A URDF robot: every link pair is swept and goes to the SRDF. A mechanism of mesh parts
        sweeps only the pairs some joint moves relative to each other (the check itself judges
        the others at the pose).
    pose : dict of str -> float
        Every movable joint's value at the run's pose, where its parts are placed
        (``joint_values``; mimic joints included).
    srdf : load.srdf.Srdf or None
        The SRDF of this robot whose disabled pairs the run audits (``--audit-srdf``).
    """

    robot: Robot
    parts: dict[str, list[int]]
    units: str = "m"
    adjacent: set[frozenset[str]] = field(default_factory=set)
    is_urdf: bool = True
    pose: dict[str, float] = field(default_factory=dict)
    srdf: Srdf | None = None

    def robot_pose(self) -> RobotPose:
        """The joint values the robot was checked at, as the reports record them: every joint
        a pose sets, in the robot's order (0 for one ``pose`` lacks)."""
        joints = tuple((j.name, float(self.pose.get(j.name, 0.0))) for j in self.robot.movable)
        return RobotPose(self.robot.path, self.robot.name, joints)


# --------------------------------------------------------------------------------------------
# Poses and forward kinematics


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll (x), pitch (y), yaw (z): ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    return rotation([0, 0, 1], yaw) @ rotation([0, 1, 0], pitch) @ rotation([1, 0, 0], roll)


def rotation(axis, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about the unit ``axis`` (Rodrigues)."""
    k = cross_matrix(axis)
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def cross_matrix(axis) -> np.ndarray:
    """(3, 3) matrix ``K`` with ``K @ v == cross(axis, v)``: Rodrigues' rotation is
    ``I + sin(a) K + (1 - cos(a)) K @ K``."""
    x, y, z = np.asarray(axis, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def default_value(joint: Joint) -> float:
    """Zero, or the limit nearest zero when zero is outside the limits."""
    return min(max(0.0, joint.lower), joint.upper)


def joint_values(robot: Robot, pose=()) -> dict[str, float]:
    """Every movable joint's value at ``pose`` (JointValues), mimics following their leaders.

    Raises
    ------
    ConfigError
        A joint not in the robot or mimicking another, degrees for a prismatic joint, or a value
        beyond the joint's limits (by more than ``LIMIT_SLACK``).
    """
    values = {j.name: default_value(j) for j in robot.movable}
    for given in pose:
        joint = robot.joint(given.joint)
        where = f"{robot.path}: joint {joint.name!r}"
        if joint.mimic is not None:
            raise ConfigError(where, f"mimics {joint.mimic[0]!r}; set that joint instead")
        if joint.type not in MOVABLE:
            raise ConfigError(where, f"is {joint.type}; it takes no value")
        if given.in_degrees and joint.type not in ROTARY:
            raise ConfigError(where, "is prismatic: give metres, not degrees")
        if not joint.lower - LIMIT_SLACK <= given.value <= joint.upper + LIMIT_SLACK:
            unit = "rad" if joint.type in ROTARY else "m"
            raise ConfigError(
                where,
                f"value {given.value:.6g} {unit} is beyond its limits "
                f"[{joint.lower:.6g}, {joint.upper:.6g}] {unit}",
            )
        values[joint.name] = min(max(given.value, joint.lower), joint.upper)
    return with_mimics(robot, values)


def with_mimics(robot: Robot, values: dict[str, float]) -> dict[str, float]:
    """``values`` of the leading joints, plus every mimic joint's value from its leader."""
    out = dict(values)
    by_name = {j.name: j for j in robot.joints}

    def value(name: str) -> float:
        if name not in out:
            leader, multiplier, offset = by_name[name].mimic
            out[name] = multiplier * value(leader) + offset
        return out[name]

    for j in robot.joints:
        if j.type in MOVABLE:
            value(j.name)
    return out


def link_transforms(robot: Robot, values: dict[str, float]) -> dict[str, np.ndarray]:
    """Each link's placement in the root link's frame, (4, 4) float64, the robot's length unit."""
    out = {robot.root: np.eye(4)}
    for j in robot.joints:
        placed = out[j.parent] @ j.origin
        if j.type in MOVABLE:
            placed = placed @ j.motion(values[j.name])
        out[j.child] = placed
    return out


def adjacent_links(robot: Robot) -> set[frozenset[str]]:
    """Pairs of links joined by a joint, links without collision geometry passed through (their
    neighbours are adjacent to each other), as MoveIt's Setup Assistant decides "Adjacent"."""
    with_geometry = {c.link for c in robot.collisions}
    neighbours: dict[str, set[str]] = {link: set() for link in robot.links}
    for j in robot.joints:
        neighbours[j.parent].add(j.child)
        neighbours[j.child].add(j.parent)
    out: set[frozenset[str]] = set()
    for link in with_geometry:
        seen, frontier = {link}, [link]
        while frontier:  # walk through geometry-less links to the first ones with geometry
            at = frontier.pop()
            for other in neighbours[at] - seen:
                seen.add(other)
                if other in with_geometry:
                    out.add(frozenset((link, other)))
                else:
                    frontier.append(other)
    return out


# --------------------------------------------------------------------------------------------
# Many poses at once (the sweep's)


class FoldedChain(NamedTuple):
    """A chain (``Robot.chain``) as ``geometry.chains.chain_placements`` reads it: its movable
    joints, with the fixed transforms between them folded into one matrix each
    (``fold_chain``). It depends on the chain alone, so a caller placing one chain many times
    folds it once."""

    names: tuple[str, ...]
    before: np.ndarray  # (J, 4, 4): the origins (and held joints) before each movable joint
    kinds: np.ndarray  # (J,): TURN or SLIDE
    axes: np.ndarray  # (J, 3): each movable joint's unit axis
    after: np.ndarray  # (4, 4): the origins after the last one


def fold_chain(chain: list[Joint]) -> FoldedChain:
    """``chain``'s ``FoldedChain``."""
    before, kinds, directions, names = [], [], [], []
    fixed = np.eye(4)  # origins (and held joints) since the last motion, folded into one matrix
    for joint in chain:
        fixed = fixed @ joint.origin
        if joint.type in MOVABLE:
            before.append(fixed)
            kinds.append(SLIDE if joint.type == "prismatic" else TURN)
            directions.append(joint.axis)
            names.append(joint.name)
            fixed = np.eye(4)
    return FoldedChain(
        tuple(names),
        np.reshape(before, (-1, 4, 4)),
        np.asarray(kinds, dtype=np.int64),
        np.reshape(directions, (-1, 3)),
        fixed,
    )


def chain_transforms(
    chain: FoldedChain, poses: dict, scale: float, count: int, axes: dict | None = None
) -> np.ndarray:
    """(E, 4, 4) placements of a chain's last link (``fold_chain`` of ``Robot.chain``) in the
    root frame for ``count`` poses (``{joint: (E,) values}``, ``sweep.search.chain_poses``),
    lengths times ``scale``; with ``axes``, each movable joint's axis line at each pose goes
    there, ``{name: ((E, 3) point on it, lengths times scale, (E, 3) unit direction)}``. One
    compiled loop (``geometry.chains``)."""
    values = np.empty((count, len(chain.names)))
    for k, name in enumerate(chain.names):
        values[:, k] = poses[name]
    placed, points, lines = chain_placements(
        chain.before, chain.kinds, chain.axes, chain.after, values, scale
    )
    if axes is not None:
        for k, name in enumerate(chain.names):
            axes[name] = (points[:, k], lines[:, k])
    return placed


__all__ = [
    "HELD",
    "LIMIT_SLACK",
    "MOVABLE",
    "ROTARY",
    "Collision",
    "FoldedChain",
    "Joint",
    "Mechanism",
    "Robot",
    "adjacent_links",
    "chain_transforms",
    "cross_matrix",
    "default_value",
    "fold_chain",
    "joint_values",
    "link_transforms",
    "rotation",
    "rpy_matrix",
    "with_mimics",
]
