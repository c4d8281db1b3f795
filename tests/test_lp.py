"""The compiled largest-ball LP (``geometry.lp``) against scipy's HiGHS, with hypothesis.

The oracle is ``scipy.optimize.linprog`` on the same program (maximise ``t`` subject to
``p @ x + t <= h``, ``|x_k| <= box``); it shares no code with the kernel. HiGHS stops at its own
feasibility tolerances (about 1e-7), so optima are compared to that; the kernel's own answer is
held to what it claims: its centre is feasible for its slack, and its bound, proven by its
multipliers, is at least the true optimum and within ``GAP_REL`` of the slack.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, QhullError

from meshcheck.geometry import _kernels, lp
from meshcheck.verify.depth import _hull_inradius

SETTINGS = settings(
    derandomize=True,
    deadline=None,
    max_examples=150,
    suppress_health_check=[HealthCheck.too_slow],
)

#: HiGHS's answers are optimal to its tolerances, not to the last bit.
ORACLE_TOL = 1e-6


def oracle(p: np.ndarray, h: np.ndarray, box: float) -> float:
    """The optimum ``t`` by scipy's HiGHS."""
    res = linprog(
        [0.0, 0.0, 0.0, -1.0],
        A_ub=np.c_[p, np.ones(len(p))],
        b_ub=h,
        bounds=[(-box, box)] * 3 + [(None, None)],
        method="highs",
    )
    assert res.status == 0
    return float(res.x[3])


def kernel_only(p: np.ndarray, h: np.ndarray, box: float):
    """The compiled kernel's own answer, checked, without the fallback."""
    status, x, _, y = _kernels.ball_lp(
        np.ascontiguousarray(p, dtype=np.float64),
        np.ascontiguousarray(h, dtype=np.float64),
        float(box),
        lp.MAX_ITER,
    )
    assert status == 0
    return lp._checked(p, h, box, x, y)


@st.composite
def hulls(draw) -> tuple[np.ndarray, np.ndarray]:
    """Facet planes of the hull of random points, scaled into the unit box as ``_hull_inradius``
    does: unit normals and offsets. Flat, needle-like and many-faceted hulls included."""
    n = draw(st.integers(4, 80))
    seed = draw(st.integers(0, 2**32 - 1))
    stretch = np.array(draw(st.lists(st.floats(1e-3, 1.0), min_size=3, max_size=3)))
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3)) * stretch
    if draw(st.booleans()):  # lattice points: coplanar facets, a degenerate optimum
        points = np.round(points * 3.0) / 3.0
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    scale = float(np.abs(points - centre).max()) or 1.0
    try:
        eq = ConvexHull((points - centre) / scale).equations
    except (QhullError, ValueError):
        eq = np.array([[1.0, 0, 0, -1], [-1, 0, 0, -1], [0, 1, 0, -1], [0, -1, 0, -1]])
        eq = np.r_[eq, [[0, 0, 1.0, -1], [0, 0, -1, -1]]]
    return eq[:, :3], -eq[:, 3]


@st.composite
def rows(draw) -> tuple[np.ndarray, np.ndarray, float]:
    """Arbitrary rows (any length, zero rows, duplicates, negative right-hand sides) and a box, as
    one step of the ascent poses them (plus worse)."""
    m = draw(st.integers(1, 40))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(m, 3)) * rng.choice([0.0, 1e-3, 1.0, 10.0], size=(m, 1))
    h = rng.normal(size=m) * draw(st.sampled_from([1e-3, 1.0, 1e3]))
    if m > 2 and draw(st.booleans()):
        p[1], h[1] = p[0], h[0]  # a duplicate row
    return p, h, draw(st.sampled_from([1e-4, 0.5, 1.0, 7.0]))


def check_answer(ball, p, h, box, expected):
    scale = max(box, float(np.abs(h).max()))
    assert np.all(np.abs(ball.centre) <= box)
    assert float((h - p @ ball.centre).min()) == ball.slack
    assert ball.bound >= expected - ORACLE_TOL * scale  # a proof, so never below the optimum
    assert ball.slack >= expected - ORACLE_TOL * scale  # optimal, to HiGHS's tolerance
    assert ball.bound - ball.slack <= lp.GAP_REL * scale
    assert np.all(ball.dual >= 0.0) and abs(ball.dual.sum() - 1.0) < 1e-12


@given(hulls())
@SETTINGS
def test_hull_inradius_matches_highs(plane):
    p, h = plane
    expected = oracle(p, h, 1.0)
    check_answer(kernel_only(p, h, 1.0), p, h, 1.0, expected)
    check_answer(lp.largest_ball(p, h, box=1.0), p, h, 1.0, expected)


@given(rows())
@SETTINGS
def test_any_rows_match_highs(problem):
    p, h, box = problem
    expected = oracle(p, h, box)
    ball = lp.largest_ball(p, h, box=box)
    check_answer(ball, p, h, box, expected)


@given(hulls())
@settings(derandomize=True, deadline=None, max_examples=30)
def test_answer_is_deterministic(plane):
    p, h = plane
    a, b = lp.largest_ball(p, h, box=1.0), lp.largest_ball(p.copy(), h.copy(), box=1.0)
    assert a.centre.tobytes() == b.centre.tobytes() and a.bound == b.bound


def test_scipy_takes_over_when_the_kernel_gives_up(monkeypatch):
    """An iteration limit the kernel cannot meet: the answer comes from HiGHS, checked alike."""
    rng = np.random.default_rng(7)
    eq = ConvexHull(rng.normal(size=(200, 3))).equations
    p, h = eq[:, :3], -eq[:, 3]
    status = _kernels.ball_lp(p.copy(), h.copy(), 1.0, 1)[0]
    assert status == 1  # the iteration limit
    monkeypatch.setattr(lp, "MAX_ITER", 1)
    ball = lp.largest_ball(p, h, box=1.0)
    check_answer(ball, p, h, 1.0, oracle(p, h, 1.0))


def test_cube_inradius_and_centre():
    """A cube's hull: inradius exactly half its side, centre at its middle."""
    points = np.array([[x, y, z] for x in (0, 2.0) for y in (3, 5.0) for z in (-1, 1.0)])
    bound, centre = _hull_inradius(points)
    assert bound == pytest.approx(1.0, abs=1e-11) and bound >= 1.0
    np.testing.assert_allclose(centre, [1.0, 4.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("p", "h", "box"),
    [
        (np.zeros((0, 3)), np.zeros(0), 1.0),  # no rows: nothing bounds t
        (np.eye(3), np.ones(3), 0.0),  # an empty box
    ],
)
def test_no_answer(p, h, box):
    assert lp.largest_ball(p, h, box=box) is None


def test_malformed_input_raises():
    with pytest.raises(ValueError):
        _kernels.ball_lp(np.zeros((3, 3)), np.zeros(2), 1.0, 10)
    with pytest.raises(ValueError):
        _kernels.ball_lp(np.zeros((3, 2)), np.zeros(3), 1.0, 10)
