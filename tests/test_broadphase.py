"""Sweep and prune: exactly the box pairs a brute-force overlap test finds."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.geometry.broadphase import candidate_pairs, group_pairs


def brute_force(lower, upper, margin=0.0, owner=None):
    m = len(lower)
    out = []
    for i in range(m):
        for j in range(i + 1, m):
            gap = np.maximum(lower[j] - upper[i], lower[i] - upper[j])
            if np.all(gap <= margin) and (owner is None or owner[i] != owner[j]):
                out.append((i, j))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def test_known_pairs():
    lo = np.array([[0.0, 0, 0], [2, 0, 0], [0.5, 0, 0]])
    pairs = candidate_pairs(lo, lo + 1.0)
    assert pairs.dtype == np.int64 and pairs.tolist() == [[0, 2]]
    assert candidate_pairs(lo, lo + 1.0, margin=0.5).tolist() == [[0, 2], [1, 2]]


def test_margin_admits_a_gap_up_to_margin():
    lo = np.array([[0.0, 0, 0], [1.5, 0, 0]])
    assert candidate_pairs(lo, lo + 1.0, margin=0.5).tolist() == [[0, 1]]
    assert candidate_pairs(lo, lo + 1.0, margin=0.49).tolist() == []


def test_boxes_touching_at_a_face_are_candidates():
    lo = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    assert candidate_pairs(lo, lo + 1.0).tolist() == [[0, 1]]


def test_owner_excludes_pairs_of_one_part():
    lo = np.zeros((3, 3))
    assert candidate_pairs(lo, lo + 1, owner=np.array([0, 0, 1])).tolist() == [[0, 2], [1, 2]]


def test_no_pairs_for_fewer_than_two_boxes():
    assert candidate_pairs(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0, 2)
    assert candidate_pairs(np.zeros((1, 3)), np.ones((1, 3))).shape == (0, 2)


def test_long_row_gives_only_neighbours():
    """10,000 boxes in a row: the sweep must not enumerate all 50 million pairs."""
    lo = np.zeros((10_000, 3))
    lo[:, 0] = np.arange(10_000) * 1.5
    pairs = candidate_pairs(lo, lo + 1.0, margin=0.5)
    assert len(pairs) == 9_999
    assert np.array_equal(pairs[:, 1] - pairs[:, 0], np.ones(9_999, dtype=np.int64))


coords = st.integers(-20, 20).map(float)


@settings(derandomize=True, deadline=None, max_examples=200)
@given(
    boxes=st.lists(
        st.tuples(st.tuples(coords, coords, coords), st.tuples(*[st.integers(0, 8)] * 3)),
        max_size=25,
    ),
    margin=st.sampled_from([0.0, 0.5, 1.0, 3.0]),
    owners=st.integers(1, 4),
    seed=st.integers(0, 1000),
)
def test_matches_brute_force(boxes, margin, owners, seed):
    """Integer coordinates make exact touches and exact-margin gaps common."""
    lower = np.array([b[0] for b in boxes], dtype=np.float64).reshape(-1, 3)
    upper = lower + np.array([b[1] for b in boxes], dtype=np.float64).reshape(-1, 3)
    owner = np.random.default_rng(seed).integers(0, owners, len(boxes))
    for own in (None, owner):
        got = candidate_pairs(lower, upper, margin=margin, owner=own)
        assert got.dtype == np.int64 and got.shape[1] == 2
        assert np.array_equal(got, brute_force(lower, upper, margin, own))


@settings(derandomize=True, deadline=None, max_examples=200)
@given(
    boxes=st.lists(
        st.tuples(st.tuples(coords, coords, coords), st.tuples(*[st.integers(0, 8)] * 3)),
        min_size=1,
        max_size=25,
    ),
    groups=st.integers(1, 5),
    margins=st.lists(st.sampled_from([0.0, 0.5, 1.0, 3.0]), min_size=10, max_size=10),
    chunk=st.sampled_from([1, 7, 1 << 22]),
    seed=st.integers(0, 1000),
)
def test_group_pairs_matches_brute_force(boxes, groups, margins, chunk, seed):
    """Every box of one group against every box of the other, each group pair with its own
    margin: the box pairs brute force finds between those two groups, grouped by pair."""
    lower = np.array([b[0] for b in boxes], dtype=np.float64).reshape(-1, 3)
    upper = lower + np.array([b[1] for b in boxes], dtype=np.float64).reshape(-1, 3)
    owner = np.sort(np.random.default_rng(seed).integers(0, groups, len(boxes)))
    count = np.bincount(owner, minlength=groups)
    first = np.searchsorted(owner, np.arange(groups))
    pairs = np.array([(a, b) for a in range(groups) for b in range(a + 1, groups)])
    pairs = pairs.reshape(-1, 2)
    margin = np.array(margins[: len(pairs)] + [0.0] * max(0, len(pairs) - 10))
    got, row = group_pairs(lower, upper, first, count, pairs, margin, chunk=chunk)
    assert got.dtype == np.int64 and row.dtype == np.int64 and np.all(np.diff(row) >= 0)
    expected = []
    for k, (a, b) in enumerate(pairs):
        for i, j in brute_force(lower, upper, margin[k]):
            if {owner[i], owner[j]} == {a, b}:
                expected.append((k, *((i, j) if owner[i] == a else (j, i))))
    assert sorted(zip(row.tolist(), *got.T.tolist(), strict=True)) == sorted(expected)
