"""Mechanisms in motion: which link pairs of a robot collide never, sometimes or always over its
joint ranges (``--sweep``), asking the verify stage's kernels for distances along them.

- ``mechanisms``: what the run's robots (``load.Assembly.mechanisms``) change in the check
  (adjacent links approved), which joints a sweep moves, and the order it takes the links in;
- ``kinematics``: joint ranges and the bound on how fast a joint moves a link's points;
- ``distances``: posed links' distances, from their convex pieces and their real meshes;
- ``search``: one link pair's boxes of joint values, witnesses and descent, and the work
  budget every pair draws on;
- ``run``: every robot's link pairs, the stage the pipeline calls;
- ``audit``: the link pairs an SRDF disables, swept and judged (``--audit-srdf``).
"""

from __future__ import annotations

from .audit import audit_srdf
from .mechanisms import ADJACENT, adjacent_approvals, with_adjacent_approvals
from .run import mechanism_pieces, sweep_bodies, sweep_mechanism

__all__ = [
    "ADJACENT",
    "adjacent_approvals",
    "audit_srdf",
    "mechanism_pieces",
    "sweep_bodies",
    "sweep_mechanism",
    "with_adjacent_approvals",
]
