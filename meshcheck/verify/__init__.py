"""Candidate part pairs -> exact verdicts on the real meshes, or on the exact solids.

- ``pair``: one pair's verdict (``verify_pair``, giving a ``results.PairVerdict``);
- ``depth``: bounds on the thickness of a shared solid (touching against interference);
- ``classes``: pairs that are one situation (two geometries at one placement in the pair's
  frame), decided once and moved to each (``pair_classes``);
- ``batch``: many pairs by class, the pair cache, and dispatch to the run's workers
  (``verify_classes``);
- ``brep``: the pairs of STEP solids, decided on their B-rep (``decide_on_brep``), by
  ``solids`` (OpenCASCADE only, so a worker deciding solids loads nothing else), on solids whose
  analytic B-spline faces ``analytic`` rebuilt as planes and cylinders;
- ``shells``: shells of one mesh that share volume (the loader's warning).

The names below are imported when first used: a worker importing ``verify.solids`` does not
load the mesh kernels.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..results import PairVerdict
    from .batch import verify_classes
    from .pair import verify_pair

_LAZY = {
    "PairVerdict": "..results",
    "verify_classes": ".batch",
    "verify_pair": ".pair",
}

__all__ = ["PairVerdict", "verify_classes", "verify_pair"]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
