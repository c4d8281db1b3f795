"""Candidate part pairs -> exact verdicts on the real meshes.

- ``pair``: one pair's verdict (``verify_pair``, giving a ``results.PairVerdict``);
- ``depth``: bounds on the thickness of a shared solid (touching against interference);
- ``classes``: pairs that are one situation (two geometries at one placement in the pair's
  frame), decided once and moved to each (``pair_classes``);
- ``batch``: many pairs by class, the pair cache, and dispatch to the run's workers
  (``verify_classes``, ``verify_pairs``);
- ``shells``: shells of one mesh that share volume (the loader's warning).
"""

from __future__ import annotations

from ..results import PairVerdict
from .batch import verify_classes, verify_pairs
from .pair import verify_pair

__all__ = ["PairVerdict", "verify_classes", "verify_pair", "verify_pairs"]
