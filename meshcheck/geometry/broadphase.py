"""Axis-aligned boxes -> candidate pairs, by sweep and prune on the axis of widest spread."""

from __future__ import annotations

import numpy as np


def candidate_pairs(
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    margin: float = 0.0,
    owner: np.ndarray | None = None,
) -> np.ndarray:
    """Find the box pairs that overlap once each box is grown by ``margin / 2`` on every side.

    Two boxes pass when their gap along every axis is at most ``margin``, so no pair of shapes
    closer than ``margin`` is ever pruned.

    Parameters
    ----------
    lower, upper : (m, 3) float64
        Box corners, world coordinates, model units.
    margin : float
        Largest gap, model units, that still makes a pair a candidate.
    owner : (m,) int64, optional
        Part index of each box; boxes of the same owner are never paired.

    Returns
    -------
    pairs : (k, 2) int64
        Indices ``i < j`` of candidate boxes, sorted lexicographically.

    Examples
    --------
    >>> lo = np.array([[0.0, 0, 0], [2, 0, 0], [0.5, 0, 0]])
    >>> candidate_pairs(lo, lo + 1.0).tolist()
    [[0, 2]]
    >>> candidate_pairs(lo, lo + 1.0, margin=0.5).tolist()
    [[0, 2], [1, 2]]
    """
    lower = np.asarray(lower, dtype=np.float64).reshape(-1, 3)
    upper = np.asarray(upper, dtype=np.float64).reshape(-1, 3)
    m = len(lower)
    if m < 2:
        return np.empty((0, 2), dtype=np.int64)
    lo = lower - 0.5 * margin
    hi = upper + 0.5 * margin

    # Sweep along the axis where the boxes are most spread out, so few intervals overlap.
    centres = 0.5 * (lo + hi)
    axis = int(np.argmax(centres.max(axis=0) - centres.min(axis=0)))
    order = np.argsort(lo[:, axis], kind="stable")
    lo, hi = lo[order], hi[order]

    # In sorted order, box i overlaps on the sweep axis exactly the boxes i+1 .. end[i]-1.
    end = np.searchsorted(lo[:, axis], hi[:, axis], side="right")
    counts = np.maximum(end - np.arange(1, m + 1), 0)
    if counts.sum() > SWEEP_PAIRS_PER_BOX * m:
        # Boxes spread over a plane or a volume (a plant's modules on a floor) overlap many
        # others along any one axis: a hierarchy pairs them in n log n instead.
        i, j = _hierarchy_pairs(lo, hi)
        i, j = order[i], order[j]
    else:
        first = np.repeat(np.arange(m), counts)
        offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        second = first + 1 + offsets
        keep = np.ones(len(first), dtype=bool)
        for d in range(3):  # one axis at a time: contiguous columns, no (k, 3) temporaries
            lo_d, hi_d = np.ascontiguousarray(lo[:, d]), np.ascontiguousarray(hi[:, d])
            keep &= lo_d[second] <= hi_d[first]
            keep &= lo_d[first] <= hi_d[second]
        i, j = order[first[keep]], order[second[keep]]
    if owner is not None:
        owner = np.asarray(owner)
        distinct = owner[i] != owner[j]
        i, j = i[distinct], j[distinct]
    # Lexicographic order of (i, j), i < j < m, is the order of i * m + j: one sort of integers.
    key = np.minimum(i, j).astype(np.int64, copy=False) * m + np.maximum(i, j)
    key.sort()
    pairs = np.empty((len(key), 2), dtype=np.int64)
    np.divmod(key, m, out=(pairs[:, 0], pairs[:, 1]))
    return pairs


#: Boxes a box may overlap on the sweep axis, on average, before ``candidate_pairs`` leaves the
#: one-axis sweep (which tests each of those pairs) for a bounding-volume hierarchy.
SWEEP_PAIRS_PER_BOX = 64


def _hierarchy_pairs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``i < j`` of boxes that overlap (``lo``/``hi`` already grown), from the verify
    stage's box hierarchy (``box_pairs``), tested again with the sweep's own comparison so the
    answer is the sweep's to the bit."""
    from .triangles import box_pairs

    pairs = box_pairs(lo, hi, lo, hi, 0.0)
    i, j = pairs[:, 0], pairs[:, 1]
    i, j = i[i < j], j[i < j]
    keep = np.all((lo[j] <= hi[i]) & (lo[i] <= hi[j]), axis=1)
    return i[keep], j[keep]


def group_pairs(
    lower: np.ndarray,
    upper: np.ndarray,
    first: np.ndarray,
    count: np.ndarray,
    pairs: np.ndarray,
    margin: np.ndarray,
    *,
    chunk: int = 1 << 22,
) -> tuple[np.ndarray, np.ndarray]:
    """Box pairs across given pairs of groups: for group pair ``k``, every box of one group
    against every box of the other, kept when their gap along every axis is at most
    ``margin[k]`` (as ``candidate_pairs``).

    Parameters
    ----------
    lower, upper : (m, 3) float64
        Box corners.
    first, count : (g,) int64
        Group ``q`` owns boxes ``first[q] .. first[q] + count[q] - 1``.
    pairs : (k, 2) int64
        Group pairs.
    margin : (k,) float64
        Largest gap that keeps a box pair of group pair ``k``.
    chunk : int
        Box pairs tested at once (bounds the memory).

    Returns
    -------
    box_pairs : (p, 2) int64
        ``(box of pairs[k, 0], box of pairs[k, 1])``, grouped by ``k`` in order.
    row : (p,) int64
        The group pair ``k`` of each box pair.

    Examples
    --------
    >>> lo = np.array([[0.0, 0, 0], [5, 0, 0], [1.5, 0, 0]])
    >>> first, count = np.array([0, 2]), np.array([2, 1])
    >>> pairs, margin = np.array([[0, 1]]), np.array([0.5])
    >>> box_pairs, row = group_pairs(lo, lo + 1.0, first, count, pairs, margin)
    >>> box_pairs.tolist(), row.tolist()
    ([[0, 2]], [0])
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    margin = np.broadcast_to(np.asarray(margin, dtype=np.float64), (len(pairs),))
    na, nb = count[pairs[:, 0]], count[pairs[:, 1]]
    sizes = na * nb
    out_pairs, out_rows = [], []
    k = 0
    while k < len(pairs):
        # as many group pairs as fit in one chunk (at least one)
        end = k + max(1, int(np.searchsorted(np.cumsum(sizes[k:]), chunk, side="right")))
        rows = np.repeat(np.arange(k, end), sizes[k:end])
        offset = np.arange(len(rows)) - np.repeat(
            np.cumsum(sizes[k:end]) - sizes[k:end], sizes[k:end]
        )
        a = first[pairs[rows, 0]] + offset // nb[rows]
        b = first[pairs[rows, 1]] + offset % nb[rows]
        m = margin[rows][:, None]
        keep = np.all((lower[b] - upper[a] <= m) & (lower[a] - upper[b] <= m), axis=1)
        out_pairs.append(np.stack([a[keep], b[keep]], axis=1))
        out_rows.append(rows[keep])
        k = end
    if not out_pairs:
        return np.empty((0, 2), dtype=np.int64), np.empty(0, dtype=np.int64)
    return np.concatenate(out_pairs).astype(np.int64), np.concatenate(out_rows).astype(np.int64)
