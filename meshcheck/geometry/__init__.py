"""Geometry kernels: support maps, GJK, EPA, triangle distances. No trimesh, no I/O, no printing.

The kernels are C++ (``src/``: ``support.hpp``, ``simplex.hpp``, ``gjk.hpp``, ``epa.hpp``,
``triangles.hpp``), compiled into ``meshcheck.geometry._kernels`` when the package is installed,
so no run waits for a compiler; the Python modules here check arguments and shape the answers.

Single pairs go through :func:`query` (or :func:`signed_distance`, :func:`intersects`), which
scan the raw points and need no hull. Many pairs go through :func:`pack_convex` once and
:func:`query_pairs` in one compiled call.
"""

from __future__ import annotations

try:
    from . import _kernels  # noqa: F401
except ImportError as error:  # a source checkout that was never installed
    raise ImportError(
        "meshcheck's compiled geometry kernels (meshcheck.geometry._kernels) are not built: "
        "run `pip install .` or `pip install -e .` in the repository"
    ) from error

from .gjk import (
    Contact,
    PairQuery,
    Status,
    copied_distances,
    intersects,
    placed_distances,
    query,
    query_pairs,
    signed_distance,
)
from .support import (
    ConvexPack,
    concat_packs,
    farthest_from_lines,
    pack_convex,
    place_packs,
    repeat_pack,
    support_points,
    triangle_pack,
)

__all__ = [
    "Contact",
    "ConvexPack",
    "PairQuery",
    "Status",
    "concat_packs",
    "copied_distances",
    "farthest_from_lines",
    "intersects",
    "pack_convex",
    "place_packs",
    "placed_distances",
    "query",
    "query_pairs",
    "repeat_pack",
    "signed_distance",
    "support_points",
    "triangle_pack",
]
