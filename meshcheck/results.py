"""The vocabulary of results: the verdict of a part pair (``PairVerdict``), a ``Finding`` per
pair that is not clear (naming the collision elements of a URDF link it involves), the pose a
robot was checked at (``RobotPose``), how a robot's link pairs relate over its joint ranges
(``RobotSweep``), an SRDF's disabled pairs audited over them (``SrdfAudit``), and the clash
groups findings fall into.

What a whole run found, and whether it fails, is ``outcome.CheckResult``.
"""

from __future__ import annotations

import enum
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np


class Verdict(enum.StrEnum):
    """What the real meshes of a part pair say: the one vocabulary of statuses.

    The first four are findings (they appear in reports and can fail the run); ``CLEAR`` pairs
    are not reported. ``DUPLICATE`` is a set of copies of one part placed at the same spot
    (a modelling error), decided from geometry digests and placements before verification.
    Members compare equal to their lower-case
    names, so JSON and the configuration file use the plain words.
    """

    DUPLICATE = "duplicate"
    INTERFERENCE = "interference"
    TOUCHING = "touching"
    CLEARANCE = "clearance"
    CLEAR = "clear"


#: Statuses a finding can have, most severe first.
FINDING_STATUSES = (Verdict.DUPLICATE, Verdict.INTERFERENCE, Verdict.CLEARANCE, Verdict.TOUCHING)


@dataclass(frozen=True)
class Location:
    """Where a clash is, so a person can find it in the CAD model.

    Attributes
    ----------
    centroid : (3,) float64
        Centre of the shared volume (or of the contact region), world coordinates, model units.
    lower, upper : (3,) float64
        Axis-aligned bounding box of the shared volume or contact region.
    """

    centroid: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def __eq__(self, other: object) -> bool:
        """Equal when the three points are (arrays compared by value)."""
        if not isinstance(other, Location):
            return NotImplemented
        mine, theirs = (
            (self.centroid, self.lower, self.upper),
            (other.centroid, other.lower, other.upper),
        )
        return all(np.array_equal(x, y) for x, y in zip(mine, theirs, strict=True))

    def to_dict(self) -> dict:
        return {
            "centroid": [float(x) for x in self.centroid],
            "min": [float(x) for x in self.lower],
            "max": [float(x) for x in self.upper],
        }


@dataclass(frozen=True, eq=False)
class Solid:
    """A closed triangle mesh: the solid two parts share.

    Attributes
    ----------
    vertices : (n, 3) float64
        World coordinates, model units.
    faces : (m, 3) int64
        Outward wound.
    """

    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class PairVerdict:
    """What the real meshes of one part pair say: the one record of a verdict, from the verify
    stage through the pair cache to every report and the export (which draw it, never redo it).

    Attributes
    ----------
    status : Verdict
    distance : float
        True minimum distance between the two meshes, model units; 0 when they interfere or their
        surfaces cross. For a ``CLEAR`` verdict it is the exact distance when the surfaces come
        within reach, else ``inf`` (only known to exceed the reach).
    depth : float or None
        Interference depth, model units: the thickness of the shared solid, i.e. the diameter of
        the largest ball that fits inside it; the diameter of a ball shown to fit, so never more
        than the true depth (within 1e-3 of it on the shapes of tests/test_depth.py). None
        unless interfering, or when a mesh is not closed (there is no shared solid to measure).
    volume : float or None
        Volume of the shared solid (manifold3d boolean intersection), model units cubed, when both
        meshes are closed and the pair interferes.
    location : Location or None
        Interference: centroid and box of the shared solid. Touching: the box of the contact
        region (triangle pairs within the tolerance) and its centre. Clearance: the box of the two
        closest points and their midpoint.
    is_surface_only : bool
        True when a mesh is not closed (or the boolean failed), so the verdict rests on the
        surfaces alone.
    solid : Solid or None
        The shared solid of an interference between closed meshes (what ``volume``, ``depth``
        and ``location`` measure); None otherwise.
    closest : ((3,) float64, (3,) float64) or None
        A clearance finding's two closest points, on the first mesh and on the second, world
        coordinates; None otherwise.
    """

    status: Verdict
    distance: float
    depth: float | None = None
    volume: float | None = None
    location: Location | None = None
    is_surface_only: bool = False
    solid: Solid | None = field(default=None, repr=False, compare=False)
    closest: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)

    def swapped(self) -> PairVerdict:
        """The same verdict with the two meshes' roles exchanged (``closest`` reversed)."""
        if self.closest is None:
            return self
        return replace(self, closest=(self.closest[1], self.closest[0]))


@dataclass(frozen=True)
class CollisionElement:
    """One collision element of a part made of several (a URDF link's ``<collision>``).

    Attributes
    ----------
    link : str
        The link (the part's node name).
    index : int
        Its position among the link's ``<collision>`` elements, from 0.
    name : str or None
        Its ``name`` attribute, when it has one.
    """

    link: str
    index: int
    name: str | None = None

    def label(self) -> str:
        """``LINK/INDEX``, then the name in parentheses when there is one: ``base/1 (post)``."""
        text = f"{self.link}/{self.index}"
        return text if self.name is None else f"{text} ({self.name})"

    def to_dict(self) -> dict:
        return {"link": self.link, "index": self.index, "name": self.name}


@dataclass(frozen=True)
class Finding:
    """A part pair that interferes, touches, or comes closer than the required clearance.

    Attributes
    ----------
    a, b : str
        Part names, ``a < b``.
    verdict : PairVerdict
        What the meshes say, with ``a`` the first mesh (``INTERFERENCE``, ``TOUCHING`` or
        ``CLEARANCE``); its fields are also read as the finding's own (``status``, ``distance``,
        ``depth``, ``volume``, ``location``, ``is_surface_only``, ``solid``, ``closest``).
    id : str
        Stable identifier: sorted part names and the two meshes' content.
    approval_reason : str or None
        The reason from the approval rule when the finding is an approved exception.
    tolerance : float or None
        The touching tolerance that decided this pair, model units.
    members : tuple of str
        A ``DUPLICATE`` finding's whole set of copies (sorted names, ``a`` and ``b`` the first
        two); empty otherwise.
    pattern : str
        Key of the pattern the finding repeats (``verify.patterns``): findings of one status
        with the same key are between copies of the same two geometries at the same relative
        placement; ``""`` when it repeats no other. Grouping data, not in ``to_dict``.
    elements : tuple of CollisionElement
        For a part made of several collision elements (a URDF link's): the elements the finding
        involves (``verify.elements``), the first part's then the second's; empty otherwise.
    test : str
        The clash test that judged the pair (``config.ClashTest``; its name is in ``id``);
        ``""`` in a run without clash tests.
    """

    a: str
    b: str
    verdict: PairVerdict
    id: str = ""
    approval_reason: str | None = None
    tolerance: float | None = None
    members: tuple[str, ...] = ()
    pattern: str = ""
    elements: tuple[CollisionElement, ...] = ()
    test: str = ""

    @property
    def status(self) -> Verdict:
        return self.verdict.status

    @property
    def distance(self) -> float:
        return self.verdict.distance

    @property
    def depth(self) -> float | None:
        return self.verdict.depth

    @property
    def volume(self) -> float | None:
        return self.verdict.volume

    @property
    def location(self) -> Location | None:
        return self.verdict.location

    @property
    def is_surface_only(self) -> bool:
        return self.verdict.is_surface_only

    @property
    def solid(self) -> Solid | None:
        return self.verdict.solid

    @property
    def closest(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.verdict.closest

    @property
    def is_approved(self) -> bool:
        return self.approval_reason is not None

    def to_dict(self) -> dict:
        return {
            "id": self.id,
            "a": self.a,
            "b": self.b,
            "status": str(self.status),
            "distance": float(self.distance),
            "depth": None if self.depth is None else float(self.depth),
            "volume": None if self.volume is None else float(self.volume),
            "location": None if self.location is None else self.location.to_dict(),
            "surface_only": self.is_surface_only,
            "approved": self.approval_reason,
            "tolerance": None if self.tolerance is None else float(self.tolerance),
            **({"members": list(self.members)} if self.members else {}),
            **({"elements": [e.to_dict() for e in self.elements]} if self.elements else {}),
            **({"test": self.test} if self.test else {}),
        }


@dataclass(frozen=True)
class Part:
    """A part as the report lists it."""

    name: str
    path: str
    triangles: int
    is_closed: bool
    # Convex pieces the filter used (0 when the part needed none). Run information, not part of
    # any report: it depends on the cache and on whether CoACD finished in time.
    pieces: int

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "path": self.path,
            "triangles": self.triangles,
            "closed": self.is_closed,
        }


class SweepStatus(enum.StrEnum):
    """How a pair of a robot's links relates over the swept joint ranges (``PairSweep``).

    Members compare equal to, and format as, their lower-case names, as ``Verdict``'s do.
    """

    NEVER = "never"
    SOMETIMES = "sometimes"
    ALWAYS = "always"
    UNDECIDED = "undecided"


@dataclass(frozen=True)
class PairSweep:
    """How one pair of links relates over the joint ranges.

    Attributes
    ----------
    a, b : str
        Link names, ``a < b``.
    status : SweepStatus
        ``NEVER`` (proven: every box of joint values certified apart by more than the touching
        tolerance, see ``sweep.sweep_mechanism``), ``SOMETIMES`` (a witness pose where the real
        meshes interfere or touch), ``ALWAYS`` (their relative placement does not move and they
        collide, or one is buried in the other throughout), or ``UNDECIDED`` (neither proven
        within the resolution and the sweep's box budget).
    joints : tuple of str
        The swept joints that move the pair relative to each other.
    witness : dict of str -> float or None
        For ``SOMETIMES``: the free joints' values of the worst pose found, the witness
        (radians; metres for a URDF's slide, report units for a ``[[joint]]`` slide; the other
        joints at the run's pose): candidates (the seeded samples, then each batch of box
        centres) are re-checked deepest overlap of the links' convex pieces first, and the first
        the real meshes confirm is the witness (a bad pose, not a proven maximum of the depth).
        ``{}`` for ``ALWAYS`` when nothing moves the pair.
    verdict : Verdict or None
        The real meshes' status at the witness (``INTERFERENCE`` or ``TOUCHING``).
    boxes : int
        Boxes of joint values evaluated.
    is_adjacent : bool
        The links are joined by a joint (``load.robot.adjacent_links``).
    approval_reason : str or None
        For a mechanism of ``[[joint]]`` tables, the reason of the approval rule its two parts
        match (adjacent parts: ``sweep.ADJACENT``); its collision then does not fail the run.
    """

    a: str
    b: str
    status: SweepStatus
    joints: tuple[str, ...] = ()
    witness: dict[str, float] | None = None
    verdict: Verdict | None = None
    boxes: int = 0
    is_adjacent: bool = False
    approval_reason: str | None = None

    def to_dict(self) -> dict:
        """The pair as the JSON report lists it (``pose``: the witness's joint values)."""
        return {
            "a": self.a,
            "b": self.b,
            "status": str(self.status),
            "adjacent": self.is_adjacent,
            "joints": list(self.joints),
            "pose": None if self.witness is None else dict(self.witness),
            "verdict": None if self.verdict is None else str(self.verdict),
            "approval_reason": self.approval_reason,
        }


@dataclass(frozen=True)
class RobotSweep:
    """One robot's sweep: its URDF (or configuration file), its name, every link pair's
    ``PairSweep``, and whether it is a URDF robot (the SRDF describes one).

    Attributes
    ----------
    unswept : int
        Link pairs the sweep's work budget left over: undecided, and not listed in ``pairs``
        (a hostile robot may have millions).
    work : int
        Work the sweep of this robot did (``sweep.search.WorkBudget``).
    budget : int or None
        The run's sweep budget (``motion.Motion.budget``), shared by its robots in order.
    """

    path: str
    name: str
    pairs: tuple[PairSweep, ...]
    is_urdf: bool = True
    unswept: int = 0
    work: int = 0
    budget: int | None = None

    @property
    def counts(self) -> dict[SweepStatus, int]:
        """Link pairs of each status, every status listed (``unswept`` pairs undecided)."""
        out = {s: sum(p.status == s for p in self.pairs) for s in SweepStatus}
        out[SweepStatus.UNDECIDED] += self.unswept
        return out

    def summary(self) -> str:
        """One line: how many link pairs are never, sometimes, always in contact (``always``
        only when some are), and undecided; the work done against the budget."""
        shown = ", ".join(
            f"{n} {s}" for s, n in self.counts.items() if n or s != SweepStatus.ALWAYS
        )
        adjacent = sum(p.is_adjacent for p in self.pairs)
        total = len(self.pairs) + self.unswept
        line = f"{self.path}: {total} link pairs ({adjacent} adjacent): {shown}"
        if self.unswept:
            line += f" ({self.unswept} left unswept when the budget ran out)"
        if self.budget is not None:
            line += f"; work {self.work:,} of the budget's {self.budget:,}"
        return line

    def to_dict(self) -> dict:
        """The robot's sweep as the JSON report lists it: counts by status, the work done and
        the budget, every pair swept."""
        return {
            "robot": self.path,
            "name": self.name,
            "counts": {str(s): n for s, n in self.counts.items()},
            "unswept": self.unswept,
            "work": self.work,
            "budget": self.budget,
            "pairs": [p.to_dict() for p in self.pairs],
        }


@dataclass(frozen=True)
class RobotPose:
    """The joint values one robot (or ``[[joint]]`` mechanism) was checked at.

    Attributes
    ----------
    path : str
        Its URDF (or the configuration file of its ``[[joint]]`` tables).
    name : str
    joints : tuple of (str, float)
        Every joint a pose sets (movable, not a mimic), in the robot's order, with its value:
        radians, or metres for a URDF's slide (report units for a ``[[joint]]`` slide). Joints
        the pose does not name are at 0, or at the limit nearest 0.
    """

    path: str
    name: str
    joints: tuple[tuple[str, float], ...]

    def to_dict(self) -> dict[str, float]:
        """``{joint: value}``, as ``summary.pose`` lists it for the robot."""
        return {name: float(value) for name, value in self.joints}

    def text(self) -> str:
        """The values as ``--pose`` takes them (``elbow=2.7925268,shoulder=1.5``), the joints at
        0 left out and said: ``(other joints at 0)``, or ``every joint at 0``."""
        moved = [(n, v) for n, v in self.joints if v != 0.0]
        if not moved:
            return "every joint at 0"
        values = ",".join(f"{n}={v:.9g}" for n, v in moved)
        return values if len(moved) == len(self.joints) else f"{values} (other joints at 0)"


@dataclass(frozen=True)
class AuditedPair:
    """One ``disable_collisions`` entry of an SRDF, audited over the joint ranges.

    Attributes
    ----------
    a, b : str
        Its links, ``a < b``.
    reason : str
        The entry's ``reason`` (``Never``, ``Adjacent``, ``Default``, ``User``...).
    sweep : PairSweep
        The sweep of the two links: ``NEVER`` proves the entry; ``SOMETIMES`` comes with the
        witness pose where they collide (the entry disables a real collision); ``ALWAYS``: they
        collide at every pose (disabling is right; a ``Never`` reason is not); ``UNDECIDED``:
        neither within the sweep's budget.
    line : int
        The entry's line in the SRDF, from 1.
    span : (int, int)
        Its bytes in the SRDF, ``[start, end)``: what a corrected SRDF replaces.
    """

    a: str
    b: str
    reason: str
    sweep: PairSweep
    line: int = 0
    span: tuple[int, int] = (0, 0)

    @property
    def status(self) -> SweepStatus:
        return self.sweep.status

    @property
    def is_wrong(self) -> bool:
        """The entry disables a collision that happens: a witness pose where the two links
        interfere or touch."""
        return self.sweep.status == SweepStatus.SOMETIMES

    def to_dict(self) -> dict:
        """The entry as the JSON report lists it (``pose``: the witness's joint values)."""
        return {
            "a": self.a,
            "b": self.b,
            "reason": self.reason,
            "line": self.line,
            "status": str(self.sweep.status),
            "wrong": self.is_wrong,
            "joints": list(self.sweep.joints),
            "pose": None if self.sweep.witness is None else dict(self.sweep.witness),
            "verdict": None if self.sweep.verdict is None else str(self.sweep.verdict),
        }


@dataclass(frozen=True)
class SrdfAudit:
    """An SRDF's ``disable_collisions`` entries, audited over the robot's joint ranges.

    Attributes
    ----------
    path : str
        The SRDF.
    robot : str
        The URDF it describes.
    reasons : tuple of str
        The reasons audited (entries with others are counted in ``unaudited``).
    pairs : tuple of AuditedPair
        The audited entries, in file order.
    unaudited : int
        Entries whose reason was not audited.
    source : bytes
        The SRDF's bytes, for the corrected SRDF (``reports.srdf``); not compared.
    """

    path: str
    robot: str
    reasons: tuple[str, ...]
    pairs: tuple[AuditedPair, ...]
    unaudited: int = 0
    source: bytes = field(default=b"", repr=False, compare=False)

    @property
    def counts(self) -> dict[SweepStatus, int]:
        """Audited entries of each sweep status, every status listed."""
        return {s: sum(p.status == s for p in self.pairs) for s in SweepStatus}

    def summary(self) -> str:
        """One line: how many entries were audited, and what they are."""
        c = self.counts

        def entries(n: int) -> str:
            return f"{n} entry" if n == 1 else f"{n} entries"

        text = (
            f"{self.path}: {entries(len(self.pairs))} audited "
            f"({', '.join(self.reasons) or 'every reason'}): {c[SweepStatus.NEVER]} proven never, "
            f"{c[SweepStatus.SOMETIMES]} colliding, {c[SweepStatus.ALWAYS]} always, "
            f"{c[SweepStatus.UNDECIDED]} undecided"
        )
        if self.unaudited:
            text += f"; {entries(self.unaudited)} of other reasons not audited"
        return text

    def to_dict(self) -> dict:
        """The audit as the JSON report lists it."""
        return {
            "srdf": self.path,
            "robot": self.robot,
            "reasons": list(self.reasons),
            "counts": {str(s): n for s, n in self.counts.items()},
            "unaudited": self.unaudited,
            "pairs": [p.to_dict() for p in self.pairs],
        }


def finding_id(
    name_a: str,
    digest_a: str,
    name_b: str,
    digest_b: str,
    *,
    placement_a: np.ndarray | None = None,
    placement_b: np.ndarray | None = None,
) -> str:
    """Stable 12-hex-digit ID of a part pair: sorted names, the meshes' content digests, and
    where each part is placed.

    Parameters
    ----------
    name_a, name_b : str
        The parts' names.
    digest_a, digest_b : str
        Digests of their frame-local geometry (``Body.id_digest``: the mesh's, or a STEP
        solid's B-rep product's).
    placement_a, placement_b : (4, 4) float64, optional
        Frame -> world transforms (``Body.transform``); None hashes as no placement. Moving a
        glTF node, a 3MF item or a STEP instance changes the ID, as editing an STL does.

    Examples
    --------
    >>> finding_id("a", "1", "b", "2") == finding_id("b", "2", "a", "1")
    True
    >>> moved = np.eye(4)
    >>> moved[0, 3] = 0.5
    >>> finding_id("a", "1", "b", "2") == finding_id("a", "1", "b", "2", placement_b=moved)
    False
    """
    parts = sorted([(name_a, digest_a, placement_a), (name_b, digest_b, placement_b)], key=_name)
    h = hashlib.sha256()
    for k, (name, digest, placement) in enumerate(parts):
        # surrogateescape: a file name that is not UTF-8 keeps its bytes
        text = ("\0" if k else "") + f"{name}\0{digest}"
        h.update(text.encode("utf-8", "surrogateescape"))
        if placement is not None:  # + 0.0 makes -0.0 and 0.0 one placement
            h.update(b"\0@" + (np.asarray(placement, dtype=np.float64) + 0.0).tobytes())
    return h.hexdigest()[:12]


def finding_id_in(test: str, pair_id: str) -> str:
    """Stable 12-hex-digit ID of a clash test's finding: the test's name and the pair's
    ``finding_id``, so one pair judged by two tests has two IDs (each approved, and followed
    against a baseline, on its own).

    Examples
    --------
    >>> pair = finding_id("a", "1", "b", "2")
    >>> finding_id_in("fasteners", pair) != finding_id_in("clearance", pair)
    True
    """
    text = f"test\0{test}\0{pair_id}"
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()[:12]


def _name(part: tuple) -> tuple[str, str]:
    return part[0], part[1]


@dataclass(frozen=True)
class ClashGroup:
    """Findings of one status with one cause: a part they share (one bracket clipping many
    bolts), or a pattern they repeat (forty brackets, each clipped by its bolt the same way).

    Attributes
    ----------
    id : str
        Stable 12-hex-digit ID (``group_id``): the shared part's name and the status, or the
        pattern's key (the two geometries' content and a relative placement) and the status.
    kind : str
        ``"part"`` or ``"pattern"``.
    part : str or None
        The part every member names (``"part"`` groups); None for a pattern.
    status : Verdict
    members : tuple of Finding
        Most severe first, as the reports list findings.
    test : str
        The clash test of its members (``Finding.test``); ``""`` without clash tests.
    """

    id: str
    part: str | None
    status: Verdict
    members: tuple[Finding, ...]
    kind: str = "part"
    test: str = ""

    def to_dict(self) -> dict:
        return {
            "id": self.id,
            "kind": self.kind,
            "part": self.part,
            "status": str(self.status),
            "findings": [f.id for f in self.members],
            **({"test": self.test} if self.test else {}),
        }


#: Statuses whose findings are grouped (contact by design is not a clash to triage).
GROUPED_STATUSES = (Verdict.INTERFERENCE, Verdict.CLEARANCE)


def clash_groups(findings: Sequence[Finding]) -> list[ClashGroup]:
    """Group unapproved interference (and clearance) findings by a pattern, then by a part.

    Findings of one status with one ``Finding.pattern`` key (two or more) make a pattern group
    each, largest first. Of the rest, the part named by most findings of one status makes the
    next group, its findings leave the pool, and so on while a part is named twice. Each finding
    is in at most one group; ties go by names, so the same findings always give the same groups.
    Findings of different clash tests (``Finding.test``) are never grouped together: each
    test's groups come in the order its first finding does, their IDs hold the test's name.

    Examples
    --------
    >>> v = PairVerdict(Verdict.INTERFERENCE, 0.0, depth=1.0)
    >>> fs = [Finding(b, "plate", v, id=b) for b in ("bolt1", "bolt2", "bolt3")]
    >>> [(g.part, len(g.members)) for g in clash_groups(fs)]
    [('plate', 3)]
    """
    pool = [f for f in findings if f.status in GROUPED_STATUSES and not f.is_approved]
    by_test: dict[str, list[Finding]] = {}
    for f in pool:
        by_test.setdefault(f.test, []).append(f)
    return [g for test, found in by_test.items() for g in _groups_of(test, found)]


def _groups_of(test: str, pool: list[Finding]) -> list[ClashGroup]:
    """The clash groups of one test's unapproved findings of the grouped statuses."""
    groups = _pattern_groups(test, pool)
    taken = {id(f) for g in groups for f in g.members}
    pool = [f for f in pool if id(f) not in taken]
    while True:
        counts: dict[tuple[str, Verdict], int] = {}
        for f in pool:
            for name in (f.a, f.b):
                counts[name, f.status] = counts.get((name, f.status), 0) + 1
        best = min(counts.items(), key=lambda kv: (-kv[1], kv[0][0], kv[0][1]), default=None)
        if best is None or best[1] < 2:
            return groups
        (part, status), _ = best
        members = [f for f in pool if f.status == status and part in (f.a, f.b)]
        groups.append(
            ClashGroup(group_id(part, status, test), part, status, _by_severity(members), test=test)
        )
        taken = {id(f) for f in members}
        pool = [f for f in pool if id(f) not in taken]


def _pattern_groups(test: str, pool: Sequence[Finding]) -> list[ClashGroup]:
    """A group per pattern key and status held by two findings or more, largest first."""
    by_key: dict[tuple[str, Verdict], list[Finding]] = {}
    for f in pool:
        if f.pattern:
            by_key.setdefault((f.pattern, f.status), []).append(f)
    groups = [
        ClashGroup(
            group_id(f"pattern\0{key}", status, test),
            None,
            status,
            _by_severity(members),
            kind="pattern",
            test=test,
        )
        for (key, status), members in by_key.items()
        if len(members) > 1
    ]
    return sorted(groups, key=lambda g: (-len(g.members), g.members[0].a, g.members[0].b))


def _by_severity(members: list[Finding]) -> tuple[Finding, ...]:
    return tuple(sorted(members, key=lambda f: (-(f.depth or 0.0), f.distance, f.a, f.b)))


def group_id(part: str, status: str, test: str = "") -> str:
    """Stable 12-hex-digit ID of a clash group: its shared part's name (or ``pattern\\0KEY``
    for a pattern), its status, and its clash test's name when there is one."""
    text = "\0".join(("group", str(status), part, *((test,) if test else ())))
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()[:12]
