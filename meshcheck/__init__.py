"""meshcheck: do the parts of an assembly collide, touch, or come too close?

Example
-------
>>> import meshcheck
>>> result = meshcheck.check(["sample_meshes/plate.stl", "sample_meshes/bolt_m6_a.stl"])
>>> [f.status for f in result.findings]
[]
"""

from __future__ import annotations

from .errors import ConfigError, ExitStatus, InputError, MeshcheckError, MeshcheckWarning
from .geometry import Contact, Status, intersects, query, signed_distance
from .pipeline import check
from .results import CheckResult, Finding, Location, Part

__all__ = [
    "CheckResult",
    "ConfigError",
    "Contact",
    "ExitStatus",
    "Finding",
    "InputError",
    "Location",
    "MeshcheckError",
    "MeshcheckWarning",
    "Part",
    "Status",
    "check",
    "intersects",
    "query",
    "signed_distance",
]
