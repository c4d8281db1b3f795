"""MoveIt's allowed-collision entries (SRDF ``disable_collisions``) from a sweep.

MoveIt's Setup Assistant writes these from 10,000 random poses; here each ``Never`` is proven
over the joint ranges (``meshcheck.sweep``). Entries, sorted by link names:

- ``Adjacent``: links joined by a joint (geometry-less links passed through), as MoveIt, unless
  adjacent approval is off (``--no-adjacent``): then they get the sweep's entry like any pair;
- ``Never``: proven never in contact over the swept ranges;
- ``Always``: in contact at every pose (their relative placement does not move, or one is
  buried in the other throughout).

Pairs that collide ``sometimes`` (a witness pose is known) or that the sweep left ``undecided``
get no entry: MoveIt keeps checking them.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

from ..errors import ConfigError
from ..outcome import CheckResult
from ..results import SweepStatus

#: The SRDF reason of a swept pair's status; the others get no entry.
REASONS = {SweepStatus.NEVER: "Never", SweepStatus.ALWAYS: "Always"}


def render(result: CheckResult) -> str:
    """The SRDF document of the run's one swept robot, ending with a newline.

    Raises
    ------
    ConfigError
        The run swept no robot, or several (an SRDF describes one).
    """
    robots = [r for r in result.sweeps if r.is_urdf]  # not a mechanism of [[joint]] tables
    if len(robots) != 1:
        count = "no robot" if not robots else f"{len(robots)} robots"
        raise ConfigError(None, f"--srdf writes one URDF robot's SRDF; this run swept {count}")
    (robot,) = robots
    adjacent = result.settings.motion.adjacent  # off: adjacent pairs are judged by the sweep
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f"<!-- meshcheck sweep of {_comment(robot.path)}: Never entries are proven over the "
        "joint ranges -->",
        f"<robot name={quoteattr(robot.name)}>",
    ]
    for pair in sorted(robot.pairs, key=lambda p: (p.a, p.b)):
        reason = "Adjacent" if pair.is_adjacent and adjacent else REASONS.get(pair.status)
        if reason is None:
            continue
        lines.append(
            f"    <disable_collisions link1={quoteattr(pair.a)} link2={quoteattr(pair.b)} "
            f"reason={quoteattr(reason)}/>"
        )
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _comment(text: str) -> str:
    """``text`` safe inside an XML comment (no ``--``, printable)."""
    return "".join(c if c.isprintable() else "?" for c in text).replace("--", "- -")
