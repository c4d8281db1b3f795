"""Mechanisms: which parts are links of a robot, which links are adjacent, and (``--sweep``)
which link pairs collide never, sometimes or always over the joint ranges.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Sequence
from dataclasses import dataclass

from .config import Approval
from .load import Body
from .load.files import URDF_EXTENSIONS
from .load.limits import Limits, read_file
from .load.urdf import Robot, adjacent_links, parse_robot

#: The reason adjacent links' findings are approved with (MoveIt's "Adjacent").
ADJACENT = "adjacent"


@dataclass(frozen=True)
class Mechanism:
    """One robot and the parts that are its links.

    Attributes
    ----------
    robot : Robot
    parts : dict of str -> list of int
        Each link's parts, as indices into the run's bodies.
    """

    robot: Robot
    parts: dict[str, list[int]]

    def link_of(self) -> dict[int, str]:
        """The link of each of the robot's parts (index into the run's bodies)."""
        return {k: link for link, ks in self.parts.items() for k in ks}


def mechanisms(bodies: Sequence[Body]) -> list[Mechanism]:
    """The robots among the bodies (every URDF file), in the order their parts come."""
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
        out.append(Mechanism(robot, parts))
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
        for pair in sorted(sorted(p) for p in adjacent_links(mech.robot)):
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
    extra = adjacent_approvals(bodies, mechanisms(bodies))
    if not extra:
        return settings
    return settings.replace(approvals=(*settings.approvals, *extra))


_NO_LIMITS = Limits(max_file_bytes=1 << 62)  # the URDF was read once already, within the limits
