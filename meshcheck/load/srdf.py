"""SRDF files -> the link pairs a MoveIt configuration disables (``--audit-srdf``).

An SRDF (MoveIt's semantic robot description) lists ``<disable_collisions link1 link2
reason>`` entries: pairs of a URDF robot's links whose collisions the planner never checks.
The audit (``sweep.audit``) sweeps each one over the joint ranges; this module reads them, with
where each entry is in the file (its line, and its bytes, which a corrected SRDF replaces,
``reports.srdf``). An SRDF names links only, never files: nothing else is read on its account.

The SRDF is an input like any other, and as hostile as any XML: it is read by the URDF reader's
parser (``urdf.parse_xml``: expat, a DOCTYPE or entity refused outright), within
``MAX_SRDF_BYTES`` and ``MAX_SRDF_ELEMENTS``. Every problem is an ``InputError`` naming the SRDF
(exit 3): unreadable, too large, malformed, a DOCTYPE, not a ``<robot>``, an entry without its
links or disabling a link against itself, links the robot does not have (named), UTF-16.
Auditing with no URDF robot, or several, in the run is a ``ConfigError`` (exit 2).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

from ..errors import ConfigError, InputError
from .limits import Limits, read_file
from .robot import Mechanism, Robot
from .urdf import parse_xml

#: Bytes of an SRDF: the PR2's, the largest of moveit_resources, is 137 kB.
MAX_SRDF_BYTES = 16 << 20
#: Elements of an SRDF: a robot of 200 links disabling every pair has about 20,000.
MAX_SRDF_ELEMENTS = 200_000
#: Unknown links an error message names before it counts the rest.
NAMED_LINKS = 5


@dataclass(frozen=True)
class DisabledPair:
    """One ``<disable_collisions>`` entry.

    Attributes
    ----------
    a, b : str
        Its links, ``a < b`` (the file's ``link1`` and ``link2``, in either order).
    reason : str
        Its ``reason`` attribute, ``""`` when it has none.
    line : int
        Its line in the file, from 1.
    span : (int, int)
        Its bytes in the file, ``[start, end)``.
    """

    a: str
    b: str
    reason: str
    line: int
    span: tuple[int, int]


@dataclass(frozen=True)
class Srdf:
    """An SRDF's disabled pairs.

    Attributes
    ----------
    path : str
        The file, as given.
    name : str
        Its ``<robot name>``.
    pairs : tuple of DisabledPair
        In file order.
    data : bytes
        The file's content (a corrected SRDF is this with entries replaced).
    """

    path: str
    name: str
    pairs: tuple[DisabledPair, ...]
    data: bytes = field(default=b"", repr=False)


def read_srdf(path: str, limits: Limits | None = None) -> Srdf:
    """Read and parse an SRDF (``parse_srdf``), within ``MAX_SRDF_BYTES``.

    Raises
    ------
    InputError
        See the module docstring.
    """
    limits = limits or Limits()
    bounded = dataclasses.replace(limits, max_file_bytes=min(limits.max_file_bytes, MAX_SRDF_BYTES))
    return parse_srdf(path, read_file(path, bounded))


def parse_srdf(path: str, data: bytes) -> Srdf:
    """The ``disable_collisions`` entries of an SRDF's bytes (links not yet checked against a
    robot: ``check_links``).

    Raises
    ------
    InputError
        See the module docstring.
    """
    if data[:2] in (b"\xff\xfe", b"\xfe\xff") or b"\x00" in data[:4]:
        raise InputError(path, "is UTF-16: meshcheck reads SRDFs in UTF-8")
    positions: dict = {}
    root = parse_xml(path, data, max_elements=MAX_SRDF_ELEMENTS, positions=positions)
    if root.tag != "robot":
        raise InputError(path, f"root element is <{root.tag}>, not <robot>: not an SRDF")
    pairs = []
    for el in root.iter("disable_collisions"):
        line, start, end = positions[id(el)]
        links = [(el.get(key) or "").strip() for key in ("link1", "link2")]
        if not all(links):
            raise InputError(path, f"line {line}: <disable_collisions> without link1 and link2")
        if links[0] == links[1]:
            raise InputError(
                path, f"line {line}: <disable_collisions> disables link {links[0]!r} against itself"
            )
        a, b = sorted(links)
        pairs.append(DisabledPair(a, b, (el.get("reason") or "").strip(), line, (start, end)))
    return Srdf(path, root.get("name", ""), tuple(pairs), data)


def check_links(srdf: Srdf, robot: Robot) -> None:
    """Refuse an SRDF whose entries name links ``robot`` does not have, naming them.

    Raises
    ------
    InputError
        Naming the SRDF, the robot's URDF and the first ``NAMED_LINKS`` unknown links.
    """
    known = set(robot.links)
    unknown = sorted({link for p in srdf.pairs for link in (p.a, p.b) if link not in known})
    if unknown:
        shown = ", ".join(repr(link) for link in unknown[:NAMED_LINKS])
        if len(unknown) > NAMED_LINKS:
            shown += f" and {len(unknown) - NAMED_LINKS} more"
        raise InputError(
            srdf.path, f"disable_collisions names links {robot.path} does not have: {shown}"
        )


def with_srdf(mechanisms: Sequence[Mechanism], path: str, limits: Limits) -> list[Mechanism]:
    """``mechanisms`` with the SRDF at ``path`` read, checked and given to the one URDF robot
    among them (``Mechanism.srdf``).

    Raises
    ------
    ConfigError
        The run has no URDF robot, or several: an SRDF describes one.
    InputError
        The SRDF cannot be read (see the module docstring).
    """
    robots = [k for k, m in enumerate(mechanisms) if m.is_urdf]
    if len(robots) != 1:
        count = "none" if not robots else f"{len(robots)}"
        raise ConfigError(
            "--audit-srdf", f"an SRDF describes one URDF robot; the inputs hold {count}"
        )
    srdf = read_srdf(path, limits)
    (k,) = robots
    check_links(srdf, mechanisms[k].robot)
    out = list(mechanisms)
    out[k] = dataclasses.replace(mechanisms[k], srdf=srdf)
    return out


__all__ = [
    "MAX_SRDF_BYTES",
    "MAX_SRDF_ELEMENTS",
    "DisabledPair",
    "Srdf",
    "check_links",
    "parse_srdf",
    "read_srdf",
    "with_srdf",
]
