"""GJK on convex hulls: status, signed distance, witness points and normal.

The classic Gilbert-Johnson-Keerthi iteration on the Minkowski difference ``D = A - B``: the
shapes meet iff ``D`` holds the origin, and their distance is the distance from the origin to
``D``. Each iteration asks for the support point of ``D`` towards the origin and replaces the
simplex by the smallest face of (simplex + new point) nearest the origin, by one small function
per simplex size (``do_simplex2/3/4`` in ``src/simplex.hpp``, as libccd).

Like parry, the iteration keeps two bounds on the signed distance ``sd``:

* ``upper = |v|``, where ``v`` is the simplex point nearest the origin (a point of ``D``);
* ``lower = max over iterations of (w . v) / |v|`` for the support point ``w`` along ``-v``:
  ``D`` lies in the half-space ``{x : x . v/|v| >= lower}``. This is a bound on the *signed*
  distance, negative when the shapes overlap.

and the answer follows from them against the tolerance ``tol``:

* ``lower > tol``                          -> SEPARATED (distance ``upper`` once converged);
* ``upper <= tol and lower >= -tol``       -> TOUCHING (so a "distance 0" always rests on one
  more support point than the simplex that produced it, as MuJoCo's fix for false zeros);
* the origin on or inside the simplex      -> EPA, ``src/epa.hpp`` (touching, or the depth);
* neither after ``GJK_MAX_ITER``           -> UNDECIDED, never SEPARATED.

Both shapes are re-centred on a common point before iterating (Bullet), so parts 1e5 units from
the origin keep their digits. Every Minkowski point keeps its two source points, which give the
witness points.

The iteration itself is C++ (``src/gjk.hpp``, compiled into ``meshcheck.geometry._kernels`` at
``pip install``, so no run waits for a compiler); this module checks the arguments and shapes
the answers.
"""

from __future__ import annotations

import enum
import os
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import _kernels
from .constants import PARALLEL_MIN_PAIRS, SEPARATED, TOUCHING
from .support import ConvexPack

__all__ = [
    "Contact",
    "PairQuery",
    "Status",
    "intersects",
    "placed_distances",
    "query",
    "query_pairs",
    "signed_distance",
]


class Status(enum.IntEnum):
    """How two convex shapes relate, given a tolerance."""

    SEPARATED = 0
    """The distance exceeds the tolerance."""
    TOUCHING = 1
    """The signed distance is within the tolerance of 0."""
    PENETRATING = 2
    """The shapes overlap by more than the tolerance."""
    UNDECIDED = 3
    """Iteration limit or numerical trouble; treat as "maybe meeting". Never NaN."""


@dataclass(frozen=True, eq=False)
class Contact:
    """The answer of :func:`query` for one pair of convex shapes.

    Attributes
    ----------
    status : Status
    distance : float
        Signed distance, model units: > 0 the gap, < 0 minus the penetration depth, near 0
        when touching. For UNDECIDED a lower bound of the signed distance (0.0 if none).
    point_a : (3,) float64
        Witness point on A, world coordinates: the closest point; when penetrating, the
        deepest point of A inside B along ``normal``.
    point_b : (3,) float64
        Witness point on B. ``point_b - point_a == distance * normal`` up to rounding.
    normal : (3,) float64
        Unit vector from A toward B: the direction along the gap, or the direction to move B
        by ``-distance`` to separate the shapes.
    """

    status: Status
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray


class PairQuery(NamedTuple):
    """The answers of :func:`query_pairs`, one row per pair.

    Attributes
    ----------
    status : (k,) int8
        :class:`Status` codes.
    distance : (k,) float64
        Signed distances, model units (see :func:`query_pairs` for the early exits).
    point_a, point_b : (k, 3) float64
        Witness points, world coordinates.
    normal : (k, 3) float64
        Unit normals from A toward B.
    """

    status: np.ndarray
    distance: np.ndarray
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray


def _contiguous(x, dtype) -> np.ndarray:
    """``x`` as a C-contiguous array of ``dtype``, copied only if needed (the kernels read
    exactly these array types)."""
    return np.ascontiguousarray(x, dtype=dtype)


def _points(x, name: str) -> np.ndarray:
    if (
        type(x) is np.ndarray
        and x.dtype == np.float64
        and x.ndim == 2
        and x.shape[1] == 3
        and x.shape[0] > 0
        and x.flags.c_contiguous
    ):
        return x
    arr = _contiguous(x, np.float64)
    if arr.ndim == 1 and arr.size == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ValueError(f"{name}: expected an (n, 3) array of points with n >= 1, got {arr.shape}")
    return arr


def _tolerance(tolerance) -> float:
    if tolerance is None:
        return -1.0
    tol = float(tolerance)
    if not tol >= 0.0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")
    return tol


def _run(a, b, tolerance, want_depth: bool) -> np.ndarray:
    out = _kernels.query_points(_points(a, "a"), _points(b, "b"), _tolerance(tolerance), want_depth)
    if out[0] < 0.0:
        raise ValueError("a, b: coordinates must be finite")
    return out


def query(a, b, *, tolerance: float | None = None) -> Contact:
    """Relate two convex hulls: status, signed distance, witness points and normal.

    Parameters
    ----------
    a, b : (n, 3) array-like of float
        Points in world coordinates, model units, each taken as its convex hull (n >= 1: a
        point, segment, flat polygon or solid). No hull is computed: the support map scans
        the points, so any extra interior points only cost time.
    tolerance : float, optional, keyword-only
        Touching tolerance, absolute, model units. Default: ``TOUCH_REL`` times the larger AABB
        edge of the two shapes, at least ``COORD_REL`` times their largest coordinate (see
        :mod:`meshcheck.geometry.constants`).

    Returns
    -------
    Contact

    Raises
    ------
    ValueError
        A shape is not an (n, 3) array with n >= 1, has non-finite coordinates, or the
        tolerance is negative.

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> c = query(cube, cube + [3.0, 0.0, 0.0])
    >>> c.status.name, round(c.distance, 12), c.normal.tolist()
    ('SEPARATED', 2.0, [1.0, 0.0, 0.0])
    """
    out = _run(a, b, tolerance, True)
    return Contact(
        Status(int(out[0])), float(out[1]), out[2:5].copy(), out[5:8].copy(), out[8:11].copy()
    )


def signed_distance(a, b, *, tolerance: float | None = None) -> float:
    """Signed distance between two convex hulls: gap > 0, minus the penetration depth < 0.

    Exactly 0.0 when the shapes touch within ``tolerance``. Parameters as :func:`query`.

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> round(signed_distance(cube, cube + [0.75, 0.0, 0.0]), 12)
    -0.25
    >>> signed_distance(cube, cube + [1.0, 0.0, 0.0])
    0.0
    """
    out = _run(a, b, tolerance, True)
    return 0.0 if out[0] == TOUCHING else float(out[1])


def intersects(a, b, *, tolerance: float | None = None) -> bool:
    """Whether two convex hulls meet: touching, penetrating, or undecided (conservatively).

    Parameters as :func:`query`; skips the penetration depth.

    Examples
    --------
    >>> import numpy as np
    >>> intersects([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1e-3]])
    False
    """
    out = _run(a, b, tolerance, False)
    return bool(out[0] != SEPARATED)


# ---------------------------------------------------------------------------------------------
# Batch
# ---------------------------------------------------------------------------------------------


def _per_pair(value, k: int, name: str, default: float) -> np.ndarray:
    if value is None:
        return np.full(k, default)
    arr = np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), (k,)))  # a fresh copy
    if np.isnan(arr).any() or (arr < 0.0).any():
        raise ValueError(f"{name} must be >= 0")
    return arr


def query_pairs(
    pack: ConvexPack,
    pairs: np.ndarray,
    *,
    tolerance: float | np.ndarray | None,
    depth: bool = True,
    max_distance: float | np.ndarray | None = None,
    threads: int = 1,
) -> PairQuery:
    """Relate many pairs of packed convex shapes in one compiled call.

    Parameters
    ----------
    pack : ConvexPack
        The shapes, from :func:`meshcheck.geometry.pack_convex` / ``concat_packs``.
    pairs : (k, 2) int64
        Shape indices into ``pack``; ``i < j`` by convention, any order works.
    tolerance : float or (k,) float64 or None, keyword-only
        Touching tolerance, absolute, model units. None: the default of :func:`query`, per pair.
    depth : bool, keyword-only
        If False, skip converging the penetration depth: a PENETRATING pair then gets
        ``distance = -L`` where ``0 < tol < L <= depth`` is a lower bound of its depth (the
        status is exact; the witness points and normal are those of the EPA face that gave L).
    max_distance : float or (k,) float64, optional, keyword-only
        Early exit: as soon as the distance is known to exceed ``max(max_distance, tolerance)``
        the pair is SEPARATED with ``distance`` set to that *lower bound* (not converged) and
        witness points of the current simplex. The pipeline passes clearance + tolerance, so
        every pair with ``distance <= max_distance`` is still measured exactly.
    threads : int, keyword-only
        Threads to spread the pairs over; 0 means one per core this process may run on. Default
        1: the calling thread only, because on a shared 2-core machine (``bench/gjk.py``) a
        second thread only helps when the second core is idle, and the pipeline's CoACD workers
        often use it. The threads are started and joined within the call (no pool is left
        behind, so ``fork()`` afterwards is safe), and the GIL is released while they run.
        Fewer than ``PARALLEL_MIN_PAIRS`` pairs always run in the calling thread.

    Returns
    -------
    PairQuery
        One row per pair, in order.

    Examples
    --------
    >>> import numpy as np
    >>> from meshcheck.geometry import pack_convex
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> pack = pack_convex([cube, cube + [3.0, 0.0, 0.0], cube + [0.5, 0.0, 0.0]])
    >>> res = query_pairs(pack, np.array([[0, 1], [0, 2]]), tolerance=1e-9)
    >>> res.status.tolist(), np.round(res.distance, 12).tolist()
    ([0, 2], [2.0, -0.5])
    """
    pairs = _contiguous(pairs, np.int64)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"pairs: expected a (k, 2) array, got {pairs.shape}")
    k = pairs.shape[0]
    m = pack.starts.shape[0] - 1
    if k and (pairs.min() < 0 or pairs.max() >= m):
        raise ValueError(f"pairs: shape indices must be in [0, {m})")
    tols = _per_pair(tolerance, k, "tolerance", -1.0)
    max_dists = _per_pair(max_distance, k, "max_distance", np.inf)
    status = np.empty(k, dtype=np.int8)
    distance = np.empty(k)
    point_a = np.empty((k, 3))
    point_b = np.empty((k, 3))
    normal = np.empty((k, 3))
    if k:
        f8, i8 = np.float64, np.int64
        if threads == 0:
            threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
        threads = max(1, int(threads)) if k >= PARALLEL_MIN_PAIRS else 1
        _kernels.query_pairs(
            _contiguous(pack.points, f8), _contiguous(pack.starts, i8),
            _contiguous(pack.nbr_starts, i8), _contiguous(pack.nbrs, i8),
            _contiguous(pack.lower, f8), _contiguous(pack.upper, f8),
            pairs, tols, max_dists, bool(depth), status, distance, point_a, point_b, normal,
            threads,
        )  # fmt: skip
    return PairQuery(status, distance, point_a, point_b, normal)


#: Piece boxes compared that count as one GJK query in ``placed_distances``' work (a box test
#: takes a few nanoseconds, a query a microsecond or more).
PLACED_BOXES_PER_QUERY = 64


def _pack_arrays(pack: ConvexPack) -> list[np.ndarray]:
    """A pack's six arrays as the two-pack kernels read them: float64 or int64, contiguous."""
    return [_contiguous(x, np.float64 if x.dtype.kind == "f" else np.int64) for x in pack]


def placed_distances(
    pack_a: ConvexPack,
    pack_b: ConvexPack,
    relative: np.ndarray,
    reach: np.ndarray,
    pad_a: np.ndarray,
    pad_b: np.ndarray,
    *,
    settle: bool = False,
) -> tuple[np.ndarray, int]:
    """Lower bounds on the distance between two packs of convex pieces at E placements of the
    second in the first's frame, in one compiled call, and the work it took.

    For each placement, ``pack_b``'s points are placed by ``relative[e]``; the piece pairs
    whose bounding boxes come within ``reach[e]`` plus both pads are measured by GJK
    (``tolerance=0``), nearest boxes first, each stopping once it is past the least distance so
    far (or ``reach``) plus its pads, and none whose boxes are no nearer than that least (a box
    gap bounds the pieces' from below); the least signed distance less both pads is the answer.
    An undecided pair counts as at most 0.

    Parameters
    ----------
    pack_a, pack_b : ConvexPack
        The pieces, each in its own frame.
    relative : (E, 4, 4) float64
        ``pack_b``'s frame into ``pack_a``'s.
    reach : (E,) float64
        Distances beyond which the exact value does not matter (answers above it are bounds).
    pad_a, pad_b : (m_a,), (m_b,) float64
        Each piece stands for itself grown by this much.
    settle : bool, keyword-only
        Only whether each placement comes within ``reach`` matters: the first piece pair that
        brings a placement within reach, nearest boxes first (less their pads; ties in piece
        order), gives it that pair's distance and no more GJK.

    Returns
    -------
    lowest : (E,) float64
        ``inf`` where no piece pair's boxes come within reach; ``-inf`` where a placement is
        not finite (nothing may be certified there).
    work : int
        GJK queries run, plus the piece boxes compared over ``PLACED_BOXES_PER_QUERY`` (what
        a sweep's budget counts).

    Examples
    --------
    >>> import numpy as np
    >>> from meshcheck.geometry import pack_convex
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> pack = pack_convex([cube])
    >>> moved = np.stack([np.eye(4), np.eye(4)])
    >>> moved[:, 0, 3] = [3.0, 1.5]
    >>> placed_distances(pack, pack, moved, np.array([5.0, 5.0]), np.zeros(1), np.zeros(1))
    (array([2. , 0.5]), 2)
    """
    f8 = np.float64
    relative = _contiguous(relative, f8)
    reach = _contiguous(reach, f8)
    lowest = np.empty(len(reach))
    queries, boxes = _kernels.placed_distances(
        *_pack_arrays(pack_a),
        *_pack_arrays(pack_b),
        relative, _contiguous(pad_a, f8), _contiguous(pad_b, f8), reach, bool(settle), lowest,
    )  # fmt: skip
    return lowest, queries + boxes // PLACED_BOXES_PER_QUERY


def copied_distances(
    pack_a: ConvexPack,
    pack_b: ConvexPack,
    ta: np.ndarray,
    count_a: np.ndarray,
    tb: np.ndarray,
    count_b: np.ndarray,
    reach: np.ndarray,
    pad_a: np.ndarray,
    pad_b: np.ndarray,
    *,
    centres: tuple[np.ndarray, np.ndarray] | None = None,
    first: np.ndarray | None = None,
    settle: bool = True,
) -> tuple[np.ndarray, int]:
    """Whether the hulls of each piece's copies under several placements, less the pads, stay
    farther apart than ``reach``, for E sets of placements in one compiled call.

    For each row ``e``, piece ``i`` of ``pack_a`` stands for the convex hull of its copies
    placed by ``ta[e, :count_a[e]]``, and piece ``j`` of ``pack_b`` for that of its copies
    under ``tb[e, :count_b[e]]`` (all in one common frame); the piece pairs whose boxes come
    within ``reach[e]`` plus both pads are measured by GJK (``tolerance=0``), nearest boxes
    first; with ``settle``, the first brought within reach answers. A hull's support is the
    farthest of its copies' vertices, so each query scans ``count_a[e] + count_b[e]`` copies.

    Parameters
    ----------
    pack_a, pack_b : ConvexPack
        The pieces, each in its own frame.
    ta : (E, KA, 4, 4) float64
    count_a : (E,) int64
        How many of ``ta[e]``'s placements are used, 1 to KA.
    tb : (E, KB, 4, 4) float64
    count_b : (E,) int64
    reach : (E,) float64
    pad_a, pad_b : (m_a,), (m_b,) float64
        Each piece stands for itself grown by this much.
    centres : ((E, 4, 4), (E, 4, 4)) float64, keyword-only
        One placement of each pack per row, with ``first``: a piece pair farther apart than
        ``first[e]`` (less its pads) placed by them is passed over (the caller knows it clear
        another way). Default: none passed over.
    first : (E,) float64, keyword-only
        Negative: no piece pair of the row is passed over.
    settle : bool, keyword-only
        Only whether each row stays beyond ``reach`` matters.

    Returns
    -------
    lowest : (E,) float64
        A lower bound on every piece pair's hull distance less both pads (``inf`` where no
        boxes come within reach), exact when at most ``reach`` and the hulls are apart (at
        most 0 less the pads where they meet). With ``settle``, a value at most ``reach`` is
        some piece pair's, not the least. ``-inf`` where a placement
        is not finite or a count out of range.
    work : int
        GJK queries weighted by the copies they scan over two, plus the piece boxes compared
        over ``PLACED_BOXES_PER_QUERY``.

    Examples
    --------
    >>> import numpy as np
    >>> from meshcheck.geometry import pack_convex
    >>> cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    >>> pack = pack_convex([cube])
    >>> ta = np.stack([np.eye(4), np.eye(4)])[None]
    >>> ta[0, 1, 0, 3] = 1.0  # a's hull: [0, 2] x [0, 1] x [0, 1]
    >>> tb = np.eye(4)[None, None].copy()
    >>> tb[0, 0, 0, 3] = 3.5
    >>> one, two = np.array([1]), np.array([2])
    >>> copied_distances(pack, pack, ta, two, tb, one, np.array([3.0]), np.zeros(1), np.zeros(1))
    (array([1.5]), 1)
    >>> copied_distances(pack, pack, ta, one, tb, one, np.array([3.0]), np.zeros(1), np.zeros(1))
    (array([2.5]), 1)
    """
    f8, i8 = np.float64, np.int64
    reach = _contiguous(reach, f8)
    lowest = np.empty(len(reach))
    if centres is None:
        centres = (ta[:, 0], tb[:, 0])
        first = np.full(len(reach), -1.0)
    queries, boxes, supports = _kernels.copied_distances(
        *_pack_arrays(pack_a),
        *_pack_arrays(pack_b),
        _contiguous(centres[0], f8), _contiguous(centres[1], f8), _contiguous(first, f8),
        _contiguous(ta, f8), _contiguous(count_a, i8), _contiguous(tb, f8),
        _contiguous(count_b, i8), _contiguous(pad_a, f8), _contiguous(pad_b, f8), reach,
        bool(settle), lowest,
    )  # fmt: skip
    return lowest, max(queries, supports // 2) + boxes // PLACED_BOXES_PER_QUERY
