"""Properties of GJK / EPA checked with hypothesis against independent oracles.

Oracles (none shares code with the kernel):

* "do the hulls meet": the LP  ``A^T l = B^T m, l, m >= 0, sum l = sum m = 1`` (scipy linprog);
* distance: the QP ``min |A^T l - B^T m|`` over the same weights (scipy SLSQP), which is an
  upper bound (a feasible point), and the kernel's separating plane, which certifies a lower one;
* depth: the Minkowski difference's hull (Qhull): for a polytope holding the origin the depth
  is the least distance from the origin to a facet plane.

Oracle comparisons only use cases the oracle decides with a margin around 0.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog, minimize
from scipy.spatial import ConvexHull, QhullError
from scipy.spatial.transform import Rotation

from meshcheck.geometry import Status, pack_convex, query, query_pairs, signed_distance
from meshcheck.geometry.constants import HILL_CLIMB_MIN_VERTICES

SETTINGS = settings(
    derandomize=True,
    deadline=None,
    max_examples=60,
    suppress_health_check=[HealthCheck.too_slow],
)
MARGIN = 1e-4  # oracle cases closer than this to 0 are left out


# --- strategies -------------------------------------------------------------------------------


@st.composite
def shapes(draw, *, max_points: int = 14) -> np.ndarray:
    """A point, segment, triangle, flat polygon or solid, about unit size, near the origin."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["point", "segment", "triangle", "flat", "solid", "solid"]))
    n = {"point": 1, "segment": 2, "triangle": 3}.get(kind, draw(st.integers(4, max_points)))
    pts = rng.uniform(-0.5, 0.5, size=(n, 3))
    if kind == "flat":
        pts[:, 2] = 0.0
        pts = Rotation.random(random_state=seed).apply(pts)
    if draw(st.booleans()):  # stretch it: thin slabs and needles
        pts = pts * rng.uniform(0.05, 2.0, size=3)
    return pts


@st.composite
def shape_pairs(draw, *, spread: float = 1.2):
    a = draw(shapes())
    b = draw(shapes())
    offset = np.array(draw(st.tuples(*[st.floats(-spread, spread)] * 3)))
    return a, b + offset


# --- oracles ----------------------------------------------------------------------------------


def lp_meet(a: np.ndarray, b: np.ndarray) -> bool:
    na, nb = len(a), len(b)
    a_eq = np.zeros((5, na + nb))
    a_eq[:3, :na] = a.T
    a_eq[:3, na:] = -b.T
    a_eq[3, :na] = 1.0
    a_eq[4, na:] = 1.0
    res = linprog(np.zeros(na + nb), A_eq=a_eq, b_eq=[0, 0, 0, 1, 1], bounds=(0, None))
    return res.status == 0


def qp_distance(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = len(a), len(b)

    def f(x):
        d = a.T @ x[:na] - b.T @ x[na:]
        return d @ d, np.concatenate([2 * a @ d, -2 * b @ d])

    best = np.inf
    for start in (np.concatenate([np.full(na, 1 / na), np.full(nb, 1 / nb)]),):
        res = minimize(
            f,
            start,
            jac=True,
            method="SLSQP",
            bounds=[(0, 1)] * (na + nb),
            constraints=[
                {"type": "eq", "fun": lambda x: x[:na].sum() - 1},
                {"type": "eq", "fun": lambda x: x[na:].sum() - 1},
            ],
            options={"ftol": 1e-16, "maxiter": 1000},
        )
        x = np.clip(res.x, 0, None)
        x[:na] /= x[:na].sum()
        x[na:] /= x[na:].sum()
        best = min(best, float(np.linalg.norm(a.T @ x[:na] - b.T @ x[na:])))
    return best


def minkowski_depth(a: np.ndarray, b: np.ndarray) -> float | None:
    """Depth of the origin inside hull(a_i - b_j), or None if not full-dimensional / outside."""
    diff = (a[:, None, :] - b[None, :, :]).reshape(-1, 3)
    try:
        hull = ConvexHull(diff)
    except QhullError:
        return None
    offsets = hull.equations[:, 3]  # n . x + offset <= 0 inside, |n| = 1
    if (offsets > 0).any():
        return None
    return float(-offsets.max())


# --- distance, meeting and depth against the oracles ----------------------------------------


@SETTINGS
@given(shape_pairs(spread=2.5))
def test_distance_agrees_with_qp_and_is_certified(pair):
    a, b = pair
    c = query(a, b, tolerance=1e-12)
    assert np.isfinite([c.distance, *c.point_a, *c.point_b, *c.normal]).all()
    assert c.status != Status.UNDECIDED
    oracle = qp_distance(a, b)
    assume(oracle > MARGIN)
    assert c.status == Status.SEPARATED
    # The QP point is feasible: the true distance is no larger.
    assert c.distance <= oracle * (1 + 1e-9) + 1e-12
    assert c.distance == pytest.approx(oracle, rel=1e-5, abs=1e-8)
    # The kernel's own certificate: witness points on the hulls' bounding planes, a plane
    # between them with the gap it claims.
    assert (a @ c.normal).max() <= c.point_a @ c.normal + 1e-12
    assert (b @ c.normal).min() >= c.point_b @ c.normal - 1e-12
    np.testing.assert_allclose(c.point_b - c.point_a, c.distance * c.normal, atol=1e-12)


@SETTINGS
@given(shape_pairs(spread=0.8))
def test_meeting_agrees_with_lp(pair):
    a, b = pair
    c = query(a, b, tolerance=1e-12)
    assert c.status != Status.UNDECIDED
    meet = lp_meet(a, b)
    if c.status == Status.SEPARATED:
        assert not meet or c.distance < MARGIN
    elif c.status == Status.PENETRATING:
        assert meet
    if meet:
        assert c.status != Status.SEPARATED or c.distance < MARGIN
    else:
        assert qp_distance(a, b) == pytest.approx(max(c.distance, 0), rel=1e-5, abs=1e-8)


@SETTINGS
@given(shape_pairs(spread=0.6))
def test_depth_agrees_with_minkowski_facets(pair):
    a, b = pair
    depth = minkowski_depth(a, b)
    assume(depth is not None and depth > MARGIN)
    c = query(a, b, tolerance=1e-12)
    assert c.status == Status.PENETRATING
    assert -c.distance == pytest.approx(depth, rel=1e-6, abs=1e-10)
    # The normal is the facet's: moving B by the depth along it leaves the hulls touching.
    moved = query(a, b + (depth + 1e-7) * c.normal, tolerance=1e-6)
    assert moved.status == Status.TOUCHING
    # depth=False keeps the status and gives a lower bound of the depth
    quick = query_pairs(pack_convex([a, b]), np.array([[0, 1]]), tolerance=1e-12, depth=False)
    assert quick.status[0] == Status.PENETRATING
    assert -depth * (1 + 1e-9) <= quick.distance[0] < 0


@SETTINGS
@given(
    st.tuples(*[st.floats(0.1, 2.0)] * 3),
    st.tuples(*[st.floats(0.1, 2.0)] * 3),
    st.tuples(*[st.floats(-1.5, 1.5)] * 3),
    st.integers(0, 1000),
)
def test_box_depth_and_normal(size_a, size_b, offset, seed):
    """Overlapping boxes: the depth is the least overlap along an axis."""
    ha, hb, off = np.array(size_a) / 2, np.array(size_b) / 2, np.array(offset)
    moves = np.concatenate([ha + hb - off, ha + hb + off])  # move B along +x, +y, +z, -x, -y, -z
    assume((moves > MARGIN).all())
    depth = moves.min()
    assume(np.sort(moves)[1] - depth > MARGIN)  # a unique best direction
    unit = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    rot = Rotation.random(random_state=seed)
    a = rot.apply(unit * ha)
    b = rot.apply(unit * hb + off)
    c = query(a, b)
    assert c.status == Status.PENETRATING
    assert c.distance == pytest.approx(-depth, rel=1e-9, abs=1e-12)
    best = int(np.argmin(moves))
    normal = (1.0 if best < 3 else -1.0) * rot.as_matrix()[:, best % 3]
    np.testing.assert_allclose(c.normal, normal, atol=1e-9)


# --- symmetry, invariance, monotonicity -------------------------------------------------------


@SETTINGS
@given(shape_pairs())
def test_symmetry(pair):
    a, b = pair
    ab = query(a, b, tolerance=1e-10)
    ba = query(b, a, tolerance=1e-10)
    assert ab.status == ba.status
    assert ab.distance == pytest.approx(ba.distance, rel=1e-7, abs=1e-10)
    if ab.status == Status.SEPARATED and ab.distance > MARGIN:
        np.testing.assert_allclose(ab.normal, -ba.normal, atol=1e-6)


@SETTINGS
@given(shape_pairs(), st.integers(0, 10_000), st.sampled_from([0.0, 10.0, 1e5]))
def test_rigid_transform_invariance(pair, seed, far):
    a, b = pair
    rng = np.random.default_rng(seed)
    rot = Rotation.random(random_state=seed)
    shift = far * rng.uniform(-1, 1, size=3)
    base = query(a, b, tolerance=1e-6)
    moved = query(rot.apply(a) + shift, rot.apply(b) + shift, tolerance=1e-6)
    ulp = np.spacing(far + 3.0)
    if abs(base.distance) > 1e-5:  # clear of the tolerance band
        assert moved.status == base.status
    if Status.UNDECIDED in (base.status, moved.status):
        assert abs(base.distance) < 1e-5 and abs(moved.distance) < 1e-5
        return
    assert moved.distance == pytest.approx(base.distance, rel=1e-7, abs=64 * ulp + 1e-12)
    if base.status == Status.SEPARATED and base.distance > MARGIN:
        np.testing.assert_allclose(moved.normal, rot.apply(base.normal), atol=1e-6)


@SETTINGS
@given(shape_pairs(spread=1.0), st.floats(1e-3, 1.0))
def test_scale_invariance(pair, scale_exp):
    a, b = pair
    s = 10.0 ** (8 * scale_exp - 4)  # 1e-4 .. 1e4
    base = query(a, b)
    scaled = query(s * a, s * b)
    if Status.UNDECIDED in (base.status, scaled.status):
        # only allowed where float64 cannot tell touching from a sliver gap
        assert abs(base.distance) < 1e-6 and abs(scaled.distance) < 1e-6 * s
        return
    assert scaled.status == base.status
    assert scaled.distance == pytest.approx(s * base.distance, rel=1e-7, abs=1e-12 * s)


@SETTINGS
@given(shape_pairs(spread=1.0))
def test_moving_apart_along_the_normal_is_monotone(pair):
    a, b = pair
    c = query(a, b, tolerance=1e-10)
    assume(c.status != Status.TOUCHING)
    previous = c.distance
    for t in (1e-6, 1e-3, 0.1, 0.5, 2.0):
        d = signed_distance(a, b + t * c.normal, tolerance=1e-10)
        assert d >= previous - 1e-9
        if c.status == Status.SEPARATED:
            # the separating plane moves with B: the gap grows by exactly t
            assert d == pytest.approx(c.distance + t, rel=1e-9, abs=1e-12)
        previous = d
    assert previous > 0  # 2.0 along the normal clears any overlap of unit-sized shapes


# --- batch ------------------------------------------------------------------------------------


@SETTINGS
@given(st.lists(shapes(max_points=60), min_size=2, max_size=6), st.integers(0, 1000))
def test_query_pairs_agrees_with_query(shape_list, seed):
    rng = np.random.default_rng(seed)
    shape_list = [s + rng.uniform(-1.0, 1.0, size=3) for s in shape_list]
    # one big hull so hill climbing is exercised
    ball = rng.normal(size=(HILL_CLIMB_MIN_VERTICES + 20, 3))
    shape_list.append(0.6 * ball / np.linalg.norm(ball, axis=1, keepdims=True))
    pack = pack_convex(shape_list)
    m = len(shape_list)
    pairs = np.array([[i, j] for i in range(m) for j in range(i + 1, m)], dtype=np.int64)
    res = query_pairs(pack, pairs, tolerance=1e-9)
    for row, (i, j) in enumerate(pairs):
        c = query(shape_list[i], shape_list[j], tolerance=1e-9)
        assert res.status[row] == c.status
        assert res.distance[row] == pytest.approx(c.distance, rel=1e-7, abs=1e-10)
    quick = query_pairs(pack, pairs, tolerance=1e-9, depth=False, max_distance=0.3)
    for row in range(len(pairs)):
        if res.distance[row] <= 0.3:
            assert quick.status[row] == res.status[row]
        else:
            assert quick.status[row] == Status.SEPARATED
            assert 0.3 < quick.distance[row] <= res.distance[row] * (1 + 1e-9) + 1e-12
