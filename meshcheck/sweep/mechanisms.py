"""What the run's mechanisms (``load.Assembly.mechanisms``) change in the check and the sweep:
adjacent links' findings approved, the joints a sweep moves, the order it takes the link pairs
in, the link pairs an SRDF audit sweeps, and the approval reasons of a ``[[joint]]``
mechanism's swept pairs."""

from __future__ import annotations

import dataclasses
import glob
from collections.abc import Iterator, Sequence

from ..config import Approval, approval_reason
from ..errors import ConfigError
from ..load import Body
from ..load.robot import Mechanism, Robot
from ..results import RobotSweep

#: The reason adjacent links' findings are approved with (MoveIt's "Adjacent").
ADJACENT = "adjacent"


def adjacent_approvals(bodies: Sequence[Body], mechanisms: Sequence[Mechanism]) -> list[Approval]:
    """An approval (reason ``ADJACENT``) for each pair of parts on adjacent links.

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts.
    mechanisms : sequence of Mechanism
        The robots among them (``load.Assembly.mechanisms``).
    """
    out = []
    for mech in mechanisms:
        for pair in sorted(sorted(p) for p in mech.adjacent):
            a, b = pair
            for i in mech.parts.get(a, ()):
                for j in mech.parts.get(b, ()):
                    out.append(
                        Approval(glob.escape(bodies[i].name), glob.escape(bodies[j].name), ADJACENT)
                    )
    return out


def with_adjacent_approvals(settings, bodies: Sequence[Body], mechanisms: Sequence[Mechanism]):
    """``settings`` with the approvals the robots among ``bodies`` bring: adjacent links'
    pairs (after the user's own rules, whose reasons win), unless ``settings.motion.adjacent``
    is off."""
    if not settings.motion.adjacent:
        return settings
    extra = adjacent_approvals(bodies, mechanisms)
    if not extra:
        return settings
    return settings.replace(approvals=(*settings.approvals, *extra))


def check_swept(mechanisms: Sequence[Mechanism], named) -> None:
    """Refuse a joint of ``--sweep-joints`` that no mechanism of the run has (``ConfigError``
    from the first robot, listing its joints)."""
    for name in named or ():
        if mechanisms and not any(name in {j.name for j in m.robot.joints} for m in mechanisms):
            mechanisms[0].robot.joint(name)  # raises, naming the robot's movable joints


def swept_joints(robot: Robot, named) -> set[str]:
    """The joints of ``robot`` swept: every movable one when ``named`` is empty, else those of
    ``named`` it has (``check_swept`` refused names no mechanism of the run has)."""
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


def link_order(mech: Mechanism) -> list[str]:
    """The mechanism's links with parts, root first, each after its parent (joint order): the
    order the sweep's budget reaches them in."""
    robot = mech.robot
    order = [robot.root, *(j.child for j in robot.joints)]
    seen: set[str] = set()
    return [n for n in order if n in mech.parts and not (n in seen or seen.add(n))]


def pairs_in_order(
    links: Sequence[str], wanted: set[frozenset[str]] | None = None
) -> Iterator[tuple[str, str]]:
    """Every pair of ``links`` (each pair's names sorted), or only those in ``wanted``, the later
    link's pairs after all pairs of the links before it: a budget that runs out leaves the
    pairs of the last links, and the first ``k (k - 1) / 2`` pairs need only the first ``k``
    links."""
    for j, b in enumerate(links):
        for a in links[:j]:
            if wanted is None or frozenset((a, b)) in wanted:
                yield (a, b) if a < b else (b, a)


def pair_count(mech: Mechanism, wanted: set[frozenset[str]] | None = None) -> int:
    """How many pairs ``pairs_in_order`` gives over all the mechanism's links."""
    count = len(link_order(mech))
    if wanted is None:
        return count * (count - 1) // 2
    return sum(len(p) == 2 and all(link in mech.parts for link in p) for p in wanted)


def links_within(
    mech: Mechanism, pairs: int, wanted: set[frozenset[str]] | None = None
) -> list[str]:
    """The links (``link_order``) of the first ``pairs`` link pairs (``pairs_in_order``, of
    ``wanted`` when given)."""
    order = link_order(mech)
    if wanted is None:
        count = 0
        while count < len(order) and count * (count - 1) // 2 < pairs:
            count += 1
        return order[:count]
    position = {link: k for k, link in enumerate(order)}
    last = sorted(
        max(position[link] for link in p)
        for p in wanted
        if len(p) == 2 and all(link in position for link in p)
    )
    return order[: last[pairs - 1] + 1] if len(last) >= pairs else order


def is_audited(reason: str, reasons: Sequence[str]) -> bool:
    """Whether an SRDF entry with ``reason`` is audited (``Motion.audit_reasons``: empty for
    every entry; reasons compare without regard to case, as MoveIt writes them capitalised)."""
    return not reasons or reason.casefold() in {r.casefold() for r in reasons}


def audited_pairs(srdf, motion) -> set[frozenset[str]]:
    """The link pairs of an SRDF (``load.srdf.Srdf``) an audit sweeps: its entries whose
    reason ``motion.audit_reasons`` names."""
    return {frozenset((p.a, p.b)) for p in srdf.pairs if is_audited(p.reason, motion.audit_reasons)}


def with_approval_reasons(
    sweeps: Sequence[RobotSweep], bodies: Sequence[Body], approvals: Sequence[Approval]
) -> tuple[RobotSweep, ...]:
    """The sweeps with each ``[[joint]]`` mechanism's pair given the reason of the approval
    rule its two parts (links named by the parts' full names) match, if any."""
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
