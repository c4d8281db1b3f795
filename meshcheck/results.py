"""What a check finds: a ``Finding`` per part pair that is not clear, and the ``CheckResult``."""

from __future__ import annotations

import enum
import hashlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .baseline import Baseline
    from .settings import Settings


class Verdict(enum.StrEnum):
    """What the real meshes of a part pair say: the one vocabulary of statuses.

    The first three are findings (they appear in reports and can fail the run); ``CLEAR`` pairs
    are not reported. Members compare equal to their lower-case names, so JSON and the
    configuration file use the plain words.
    """

    INTERFERENCE = "interference"
    TOUCHING = "touching"
    CLEARANCE = "clearance"
    CLEAR = "clear"


#: Statuses a finding can have, most severe first.
FINDING_STATUSES = (Verdict.INTERFERENCE, Verdict.CLEARANCE, Verdict.TOUCHING)


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

    def to_dict(self) -> dict:
        return {
            "centroid": [float(x) for x in self.centroid],
            "min": [float(x) for x in self.lower],
            "max": [float(x) for x in self.upper],
        }


@dataclass(frozen=True)
class Finding:
    """A part pair that interferes, touches, or comes closer than the required clearance.

    Attributes
    ----------
    a, b : str
        Part names, ``a < b``.
    status : Verdict
        ``INTERFERENCE``, ``TOUCHING`` or ``CLEARANCE``.
    distance : float
        True minimum distance between the two meshes, model units; 0 when they meet.
    depth : float or None
        Interference depth (thickness of the shared volume), model units; None unless interfering.
    volume : float or None
        Shared volume (exact boolean) when both meshes are closed, else None.
    location : Location or None
        Where the clash or the closest approach is.
    id : str
        Stable identifier: sorted part names and the two meshes' content.
    is_surface_only : bool
        True when a mesh is not closed and the verdict rests on surfaces alone.
    approval_reason : str or None
        The reason from the approval rule when the finding is an approved exception.
    tolerance : float or None
        The touching tolerance that decided this pair, model units.
    """

    a: str
    b: str
    status: Verdict
    distance: float
    depth: float | None = None
    volume: float | None = None
    location: Location | None = None
    id: str = ""
    is_surface_only: bool = False
    approval_reason: str | None = None
    tolerance: float | None = None

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
        }


@dataclass(frozen=True)
class Part:
    """A part as the report lists it."""

    name: str
    path: str
    triangles: int
    is_closed: bool
    pieces: int  # convex pieces used by the filter (0 when the part needed none)

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "path": self.path,
            "triangles": self.triangles,
            "closed": self.is_closed,
            "pieces": self.pieces,
        }


@dataclass(frozen=True)
class CheckResult:
    """Everything one check found, and the settings it ran with.

    Attributes
    ----------
    findings : list of Finding
        Sorted by part names.
    parts : list of Part
    settings : Settings
        What the check ran with; its ``fail_on`` decides ``passed``.
    checked_pairs : list of (str, str)
        The part pairs the broad phase left to check (sorted names), clear ones included.
    warnings : list of str
        The messages of the run's MeshcheckWarnings.
    units : str
        The unit every length of the result is in (``meshcheck.units``).
    bodies : tuple of load.Body
        The parts' geometry, for outputs that draw them (``--export``); not compared.
    baseline : baseline.Baseline or None
        The previous report the findings were compared with (``baseline.compare``), if any.
    sweeps : tuple of sweep.RobotSweep
        With ``--sweep``: each robot's link pairs classified over the joint ranges.
    """

    findings: list[Finding]
    parts: list[Part]
    settings: Settings
    checked_pairs: list[tuple[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    bodies: tuple = field(default=(), repr=False, compare=False)
    units: str = "mm"
    baseline: Baseline | None = None
    sweeps: tuple = ()

    @property
    def tolerance(self) -> float | None:
        """The touching tolerance the user set, or None when each pair had its own."""
        return self.settings.tolerance

    @property
    def clearance(self) -> float | None:
        return self.settings.clearance

    @property
    def fail_on(self) -> tuple[Verdict, ...]:
        return self.settings.fail_on

    def count(self, status: str) -> int:
        """Number of unapproved findings with this status."""
        return sum(1 for f in self.findings if f.status == status and not f.is_approved)

    def is_failing(self, finding: Finding) -> bool:
        """True when ``finding`` fails the run: unapproved, with a status in ``fail_on``, and new
        against the baseline when the settings ask for ``fail_on_new``."""
        if finding.is_approved or finding.status not in self.settings.fail_on:
            return False
        # Only a finding the baseline holds is spared: without a baseline, every finding is new.
        return not self.settings.fail_on_new or self.baseline_state(finding) != "active"

    def baseline_state(self, finding: Finding) -> str | None:
        """``"new"`` or ``"active"`` against the baseline; None when there is no baseline."""
        return None if self.baseline is None else self.baseline.state(finding)

    @property
    def failed(self) -> bool:
        """True when an unapproved finding has a status that fails the run."""
        return any(self.is_failing(f) for f in self.findings)

    @property
    def passed(self) -> bool:
        return not self.failed


def finding_id(name_a: str, digest_a: str, name_b: str, digest_b: str) -> str:
    """Stable 12-hex-digit ID of a part pair: sorted names and the meshes' content digests."""
    (na, da), (nb, db) = sorted([(name_a, digest_a), (name_b, digest_b)])
    text = "\0".join((na, da, nb, db))
    # surrogateescape: a file name that is not UTF-8 keeps its bytes
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()[:12]
