"""Mechanisms from mesh files: the configuration's ``[[joint]]`` tables (``motion.JointSpec``)
turn parts of an STL/GLB/... assembly into a kinematic tree, posed like a URDF robot.

The files hold the parts at joint value 0. A joint turns its ``child`` parts about the line
through ``origin`` along ``axis`` (revolute, continuous) or slides them along ``axis``
(prismatic), both in world coordinates as the files place the parts (report units), carrying
whatever is mounted on the child parts further down the tree. Parts no joint moves are the fixed
ground.

The tree is a ``load.robot.Robot``, so the pose, the sweep and the SRDF treat it as they treat a
URDF: the ground and each joint's moving frame are links without geometry (``<ground>``,
``<JOINT>``), and every part of the mechanism is a link of its own, named as the part, attached
to its frame by a fixed joint. Each ``[[joint]]``'s parent parts and child parts are adjacent
(they meet at the hinge by design), and no other pair is.

A mistake in the tables is a ``ConfigError`` naming the configuration file (exit 2): a pattern
that matches no part, a part two joints move, a joint whose parent parts move with different
joints, joints that form a cycle, a pattern that matches a URDF robot's link.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence

import numpy as np

from ..config import matches
from ..errors import ConfigError
from .formats import URDF_EXTENSIONS
from .robot import Collision, Joint, Mechanism, Robot, joint_values, link_transforms

#: The link of the parts no joint moves.
GROUND = "<ground>"


def frame(joint: str) -> str:
    """The link name of the frame ``joint`` moves."""
    return f"<{joint}>"


def mesh_mechanism(bodies: Sequence, specs: Sequence) -> Mechanism:
    """The mechanism ``specs`` (``motion.JointSpec``) make of ``bodies``.

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts, as loaded (at joint value 0).
    specs : sequence of motion.JointSpec
        Non-empty.

    Returns
    -------
    Mechanism
        Its robot's lengths are in the report unit; its links are ``GROUND``, the ``<JOINT>``
        frames and the part names (each part link has one body); the adjacent pairs are each
        joint's parent parts with its child parts.

    Raises
    ------
    ConfigError
        See the module docstring.
    """
    where = specs[0].source
    names = [(b.name, b.relative_name) for b in bodies]
    is_urdf = [os.path.splitext(b.path)[1].lower() in URDF_EXTENSIONS for b in bodies]
    moved_by: dict[int, str] = {}
    matched = {}
    for spec in specs:
        sides = {}
        for role in ("parent", "child"):
            pattern = getattr(spec, role)
            ks = [k for k, n in enumerate(names) if matches(pattern, n)]
            _check_side(spec, role, pattern, ks, bodies, is_urdf, where)
            sides[role] = ks
        both = set(sides["parent"]) & set(sides["child"])
        if both:
            part = bodies[min(both)].name
            raise ConfigError(where, f"joint {spec.name!r}: part {part!r} is its parent and child")
        for k in sides["child"]:
            if k in moved_by:
                raise ConfigError(
                    where,
                    f"part {bodies[k].name!r} is moved by two joints ({moved_by[k]!r}, "
                    f"{spec.name!r}): a part has one parent",
                )
            moved_by[k] = spec.name
        matched[spec.name] = sides
    parent_frame = {s.name: _parent_frame(s, matched[s.name]["parent"], moved_by, bodies, where)
                    for s in specs}  # fmt: skip
    ordered = _tree_order(specs, parent_frame, where)
    return _mechanism(bodies, ordered, parent_frame, moved_by, matched, is_urdf)


def _check_side(spec, role, pattern, ks, bodies, is_urdf, where) -> None:
    """Refuse a pattern that matches no part, or a URDF robot's link."""
    if not ks:
        shown = ", ".join(repr(b.relative_name) for b in bodies[:3])
        raise ConfigError(
            where,
            f"joint {spec.name!r}: {role} pattern {pattern!r} matches no part (parts are named "
            f"like {shown})",
        )
    for k in ks:
        if is_urdf[k]:
            raise ConfigError(
                where,
                f"joint {spec.name!r}: {role} pattern {pattern!r} matches {bodies[k].name!r}, a "
                "URDF robot's link (its joints come from the URDF)",
            )


def _parent_frame(spec, parents, moved_by, bodies, where) -> str:
    """The frame ``spec``'s parent parts move with; refused when they move with several."""
    frames = sorted({moved_by.get(k, "") for k in parents})
    if len(frames) > 1:
        how = [f"{bodies[min(k for k in parents if moved_by.get(k, '') == f)].name!r} "
               + (f"moved by {f!r}" if f else "fixed") for f in frames[:2]]  # fmt: skip
        raise ConfigError(
            where,
            f"joint {spec.name!r}: parent pattern {spec.parent!r} matches parts that move "
            f"differently ({', '.join(how)}): its parents must be one rigid body",
        )
    return frames[0]


def _tree_order(specs, parent_frame: dict[str, str], where) -> list:
    """The joints ordered parents first (by depth, then file order); refused when they form a
    cycle. Linear in the number of joints: each joint's depth is found once."""
    depth: dict[str, int] = {}
    for spec in specs:
        path, at = [], spec.name
        while at and at not in depth:
            if at in path:
                cycle = " -> ".join([*path[path.index(at) :], at])
                raise ConfigError(where, f"the joints form a cycle ({cycle})")
            path.append(at)
            at = parent_frame[at]
        n = depth[at] if at else -1
        for name in reversed(path):
            n += 1
            depth[name] = n
    return sorted(specs, key=lambda s: depth[s.name])


def _mechanism(bodies, ordered, parent_frame, moved_by, matched, is_urdf) -> Mechanism:
    """The ``Robot`` of validated joint tables: frames, part links, adjacency."""
    origin = {s.name: np.asarray(s.origin, dtype=np.float64) for s in ordered}
    joints = []
    for spec in ordered:
        parent = parent_frame[spec.name]
        offset = np.eye(4)
        offset[:3, 3] = origin[spec.name] - (origin[parent] if parent else 0.0)
        joints.append(
            Joint(
                spec.name,
                spec.type,
                frame(parent) if parent else GROUND,
                frame(spec.name),
                offset,
                np.asarray(spec.axis, dtype=np.float64),
                spec.lower,
                spec.upper,
            )
        )
    frame_links = [GROUND, *(frame(s.name) for s in ordered)]
    parts, collisions = {}, []
    for k, body in enumerate(bodies):
        if is_urdf[k]:
            continue
        at = frame(moved_by[k]) if k in moved_by else GROUND
        # The part's link frame is its joint's frame (on the axis): the sweep's motion bound
        # measures the part's reach from there.
        joints.append(Joint(f"<{body.name}>", "fixed", at, body.name, np.eye(4), np.zeros(3)))
        parts[body.name] = [k]
        collisions.append(Collision(body.name, 0, np.eye(4), ("part", body.name)))
    adjacent = {
        frozenset((bodies[i].name, bodies[j].name))
        for s in ordered
        for i in matched[s.name]["parent"]
        for j in matched[s.name]["child"]
    }
    robot = Robot(
        ordered[0].source or "",
        "mechanism",
        GROUND,
        (*frame_links, *parts),
        tuple(joints),
        tuple(collisions),
    )
    return Mechanism(robot, parts, bodies[0].units, adjacent, is_urdf=False)


def pose_parts(bodies: Sequence, motion) -> tuple[list, Mechanism]:
    """``bodies`` with the parts of the configuration's mechanism moved to ``motion.pose``, and
    that mechanism (``mesh_mechanism``) with its pose.

    Pose values of joints no ``[[joint]]`` table names are left to the URDF robots; without
    a URDF in the run, such a value is a ``ConfigError`` (a pose of nothing).
    """
    specs = motion.joints
    mech = mesh_mechanism(bodies, specs)
    ours = {s.name for s in specs}
    has_urdf = any(os.path.splitext(b.path)[1].lower() in URDF_EXTENSIONS for b in bodies)
    pose = []
    for value in motion.pose:
        if value.joint in ours:
            pose.append(value)
        elif not has_urdf:
            mech.robot.joint(value.joint)  # raises: no such joint
    values = joint_values(mech.robot, pose)
    mech = dataclasses.replace(mech, pose=values)
    zero = link_transforms(mech.robot, {name: 0.0 for name in values})
    placed = link_transforms(mech.robot, values)
    out = list(bodies)
    for link, (k,) in mech.parts.items():
        move = placed[link] @ np.linalg.inv(zero[link])
        if not np.array_equal(move, np.eye(4)):
            out[k] = dataclasses.replace(bodies[k], transform=move @ bodies[k].transform)
    return out, mech


__all__ = ["GROUND", "frame", "mesh_mechanism", "pose_parts"]
