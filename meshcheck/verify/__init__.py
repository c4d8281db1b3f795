"""Candidate part pairs -> exact verdicts on the real meshes.

- ``pair``: one pair's verdict (``verify_pair``, giving a ``results.PairVerdict``);
- ``depth``: bounds on the thickness of a shared solid (touching against interference);
- ``batch``: many pairs, the pair cache, and dispatch to the run's workers (``verify_pairs``);
- ``shells``: shells of one mesh that share volume (the loader's warning).
"""

from __future__ import annotations

from ..results import PairVerdict
from .batch import verify_pairs
from .pair import verify_pair

__all__ = ["PairVerdict", "verify_pair", "verify_pairs"]
