"""What a check finds: a ``Finding`` per part pair that is not clear, and the ``CheckResult``."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

INTERFERENCE = "interference"
TOUCHING = "touching"
CLEARANCE = "clearance"
STATUSES = (INTERFERENCE, TOUCHING, CLEARANCE)


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
    status : str
        ``"interference"``, ``"touching"`` or ``"clearance"``.
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
    approved : str or None
        The reason from the configuration when the finding is an approved exception.
    """

    a: str
    b: str
    status: str
    distance: float
    depth: float | None = None
    volume: float | None = None
    location: Location | None = None
    id: str = ""
    is_surface_only: bool = False
    approved: str | None = None

    def to_dict(self) -> dict:
        return {
            "id": self.id,
            "a": self.a,
            "b": self.b,
            "status": self.status,
            "distance": float(self.distance),
            "depth": None if self.depth is None else float(self.depth),
            "volume": None if self.volume is None else float(self.volume),
            "location": None if self.location is None else self.location.to_dict(),
            "surface_only": self.is_surface_only,
            "approved": self.approved,
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
    """Everything one check found, plus the settings it ran with.

    ``pairs_checked`` counts the candidate part pairs after the broad phase; ``checked_pairs``
    names them (sorted names ``(a, b)``) when the pipeline records them, for reports that list
    every pair checked. ``warnings`` holds the messages of the MeshcheckWarnings of the run.
    """

    findings: list[Finding]
    parts: list[Part]
    tolerance: float
    clearance: float | None
    pairs_checked: int = 0
    warnings: list[str] = field(default_factory=list)
    checked_pairs: list[tuple[str, str]] = field(default_factory=list)

    def count(self, status: str) -> int:
        """Number of unapproved findings with this status."""
        return sum(1 for f in self.findings if f.status == status and f.approved is None)


def finding_id(name_a: str, digest_a: str, name_b: str, digest_b: str) -> str:
    """Stable 12-hex-digit ID of a part pair: sorted names and the meshes' content digests."""
    (na, da), (nb, db) = sorted([(name_a, digest_a), (name_b, digest_b)])
    text = "\0".join((na, da, nb, db))
    return hashlib.sha256(text.encode()).hexdigest()[:12]
