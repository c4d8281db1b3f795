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

With ``--audit-srdf``, ``corrected`` writes the audited SRDF back, byte for byte but for its
audited entries: one that disables a collision (a witness pose) is replaced by a comment giving
the pose; a ``Never`` entry on links that collide at every pose gets the reason ``Always``; an
entry the sweep left undecided keeps its place, a comment before it saying so.
"""

from __future__ import annotations

import re
from xml.sax.saxutils import quoteattr

from ..errors import ConfigError
from ..outcome import CheckResult
from ..results import AuditedPair, SweepStatus

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


def corrected(result: CheckResult) -> bytes:
    """The audited SRDF with its wrong entries replaced (see the module docstring).

    Raises
    ------
    ConfigError
        The run audited no SRDF.
    """
    audit = result.audit
    if audit is None:
        raise ConfigError(None, "no SRDF was audited (--audit-srdf)")
    data, out, at = audit.source, [], 0
    for pair in sorted(audit.pairs, key=lambda p: p.span):
        start, end = pair.span
        replacement = _replacement(pair, data[start:end])
        if replacement is None:
            continue
        out.extend([data[at:start], replacement])
        at = end
    out.append(data[at:])
    return b"".join(out)


def _replacement(pair: AuditedPair, entry: bytes) -> bytes | None:
    """What an audited entry becomes in the corrected SRDF; None: it stays as it is."""
    links = f"{pair.a} / {pair.b} ({pair.reason or 'no reason'})"
    if pair.is_wrong:
        pose = ",".join(f"{n}={v:.9g}" for n, v in (pair.sweep.witness or {}).items())
        return _xml_comment(f"meshcheck: removed {links}: {pair.sweep.verdict} at pose {pose}")
    if pair.status == SweepStatus.ALWAYS and pair.reason.casefold() == "never":
        return _REASON.sub(rb"\1\2Always\2", entry, count=1)
    if pair.status == SweepStatus.UNDECIDED:
        note = f"meshcheck: {links} not proven never within the sweep's box budget"
        return _xml_comment(note) + b" " + entry
    return None


#: The ``reason`` attribute of an entry, its quote kept.
_REASON = re.compile(rb"""(\breason\s*=\s*)(["'])[^"']*\2""")


def _xml_comment(text: str) -> bytes:
    """``<!-- text -->`` in ASCII (whatever the SRDF's encoding), safe inside a comment."""
    return f"<!-- {_comment(text)} -->".encode("ascii", "backslashreplace")


def _comment(text: str) -> str:
    """``text`` safe inside an XML comment (no ``--``, printable)."""
    return "".join(c if c.isprintable() else "?" for c in text).replace("--", "- -")
