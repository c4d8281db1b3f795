"""Pure numpy/numba geometry kernels: support maps, GJK, EPA. No trimesh, no I/O, no printing.

Single pairs go through :func:`query` (or :func:`signed_distance`, :func:`intersects`), which
scan the raw points and need no hull. Many pairs go through :func:`pack_convex` once and
:func:`query_pairs` in one compiled call.
"""

from __future__ import annotations

from .gjk import (
    Contact,
    PairQuery,
    Status,
    intersects,
    query,
    query_pairs,
    signed_distance,
)
from .support import ConvexPack, concat_packs, pack_convex

__all__ = [
    "Contact",
    "ConvexPack",
    "PairQuery",
    "Status",
    "concat_packs",
    "intersects",
    "pack_convex",
    "query",
    "query_pairs",
    "signed_distance",
]
