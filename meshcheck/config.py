"""Options, tolerances and the rules that approve findings or restrict which pairs are checked."""

from __future__ import annotations

import fnmatch
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# Overlaps and gaps below this fraction of the assembly's bounding-box diagonal count as touching.
# STL stores float32 (about 7 significant digits) and CAD exporters round coordinates, so faces
# modelled as coincident land up to ~1e-6 of the model size apart; 1e-5 leaves a 10x margin while
# staying far below any clearance an engineer specifies (1 um on a 100 mm assembly).
TOLERANCE_FRACTION = 1e-5


def default_tolerance(lower: np.ndarray, upper: np.ndarray) -> float:
    """Touching tolerance for an assembly whose bounding box is ``lower``..``upper``, model units."""
    diagonal = float(np.linalg.norm(np.asarray(upper) - np.asarray(lower)))
    return TOLERANCE_FRACTION * diagonal if diagonal > 0 else TOLERANCE_FRACTION


@dataclass(frozen=True)
class Approval:
    """An approved finding: parts matching ``a`` and ``b`` (glob patterns, either order)."""

    a: str
    b: str
    reason: str

    def matches(self, name_a: str, name_b: str) -> bool:
        return (fnmatch.fnmatchcase(name_a, self.a) and fnmatch.fnmatchcase(name_b, self.b)) or (
            fnmatch.fnmatchcase(name_a, self.b) and fnmatch.fnmatchcase(name_b, self.a)
        )


@dataclass(frozen=True)
class Groups:
    """Check only parts matching one of ``a`` against parts matching one of ``b``."""

    a: tuple[str, ...]
    b: tuple[str, ...]

    def allows(self, name_a: str, name_b: str) -> bool:
        in_a = [any(fnmatch.fnmatchcase(n, p) for p in self.a) for n in (name_a, name_b)]
        in_b = [any(fnmatch.fnmatchcase(n, p) for p in self.b) for n in (name_a, name_b)]
        return (in_a[0] and in_b[1]) or (in_a[1] and in_b[0])


def approval_reason(approvals: Sequence[Approval], name_a: str, name_b: str) -> str | None:
    """The reason of the first approval that matches the pair, or None."""
    for rule in approvals:
        if rule.matches(name_a, name_b):
            return rule.reason
    return None
