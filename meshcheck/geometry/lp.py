"""The largest ball in an intersection of half-spaces and a box, with a checked answer.

``largest_ball`` solves

    maximise ``t`` subject to ``p_i . x + t <= h_i`` for every row ``i`` and ``|x_k| <= box``,

the linear program behind the inradius of a convex hull (unit normals ``p_i``: ``t`` is the
radius of the ball at ``x``) and one step of the inscribed-ball ascent (``verify.depth``). The
compiled kernel (``src/lp.hpp``: a dense simplex on the four-row dual, deterministic) answers in
microseconds where ``scipy.optimize.linprog`` spends about a millisecond setting itself up. Its
answer is checked in float64 before it is used: the centre's least slack ``t`` and the bound that
the returned dual multipliers prove (weak duality, valid for any non-negative multipliers) must
agree within ``GAP_REL`` of the problem's scale; when they do not (an iteration limit, a singular
basis, rounding on a degenerate problem), scipy's HiGHS solves it instead and its multipliers
give the bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import _kernels

#: Largest accepted gap between the bound the multipliers prove and the centre's slack, relative
#: to the problem's scale (``box`` and the largest ``|h_i|``); the kernel's own tolerance is 1e-13.
GAP_REL = 1e-9

#: Simplex iterations before the kernel gives up (then scipy solves the problem).
MAX_ITER = 10_000


@dataclass(frozen=True)
class Ball:
    """Answer of ``largest_ball``.

    Attributes
    ----------
    centre : (3,) float64
        The centre found, within the box.
    slack : float
        ``min_i (h_i - p_i . centre)``: the largest ``t`` feasible at ``centre``.
    bound : float
        ``t <= bound`` for every feasible ``(x, t)``, proven by the multipliers ``dual``.
    dual : (m,) float64
        Non-negative multipliers of the rows, summing to 1 (the box's are left out).
    """

    centre: np.ndarray
    slack: float
    bound: float
    dual: np.ndarray


def largest_ball(p: np.ndarray, h: np.ndarray, *, box: float) -> Ball | None:
    """Maximise ``t`` subject to ``p @ x + t <= h`` and ``|x_k| <= box``.

    Parameters
    ----------
    p : (m, 3) float64
        Row directions (any length; unit normals make ``t`` a distance).
    h : (m,) float64
        Right-hand sides.
    box : float
        Half-width of the box around the origin ``x`` must stay in; positive.

    Returns
    -------
    Ball or None
        None when neither the kernel nor scipy finds a feasible point (no ball fits).

    Examples
    --------
    >>> p = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    >>> ball = largest_ball(p, np.array([2.0, 0, 1, 1, 1, 1]), box=5.0)
    >>> float(ball.slack), float(ball.bound), ball.centre.tolist()
    (1.0, 1.0, [1.0, 0.0, 0.0])
    """
    p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3)
    h = np.ascontiguousarray(h, dtype=np.float64).reshape(-1)
    if not len(p) or not box > 0.0:
        return None
    scale = max(float(box), float(np.abs(h).max()))
    status, x, _, y = _kernels.ball_lp(p, h, float(box), MAX_ITER)
    if status == 0:
        ball = _checked(p, h, box, x, y)
        if ball is not None and ball.bound - ball.slack <= GAP_REL * scale:
            return ball
    return _scipy_ball(p, h, box)


def _checked(p, h, box, x, y) -> Ball | None:
    """The answer ``x`` (clipped to the box) with its slack, and the bound the multipliers ``y``
    (rows, then ``x_k <= box``, ``-x_k <= box``) prove; None when they prove nothing."""
    x = np.clip(np.asarray(x, dtype=np.float64), -box, box)
    y = np.maximum(np.asarray(y, dtype=np.float64), 0.0)
    total = float(y[: len(p)].sum())
    if not (total > 0.0 and math.isfinite(total)):
        return None
    y = y / total
    rows, boxes = y[: len(p)], y[len(p) :]
    # Weak duality: for feasible (x, t), t = sum y_i t <= y . h + box sum(w) - g . x with
    # g = p^T y + (w_0 - w_1, w_2 - w_3, w_4 - w_5), and |g . x| <= |g| sqrt(3) box.
    g = p.T @ rows + (boxes[0::2] - boxes[1::2])
    bound = float(rows @ h + box * boxes.sum() + math.sqrt(float(g @ g)) * math.sqrt(3.0) * box)
    if not math.isfinite(bound):
        return None
    slack = float((h - p @ x).min())
    return Ball(x, slack, bound, rows)


def _scipy_ball(p: np.ndarray, h: np.ndarray, box: float) -> Ball | None:
    """``largest_ball`` by scipy's HiGHS (the fallback); the bound from its multipliers."""
    from scipy.optimize import linprog

    lp = linprog(
        [0.0, 0.0, 0.0, -1.0],
        A_ub=np.c_[p, np.ones(len(p))],
        b_ub=h,
        bounds=[(-box, box)] * 3 + [(None, None)],
        method="highs",
    )
    if lp.status != 0:
        return None
    y = -np.asarray(lp.ineqlin.marginals)
    upper = -np.asarray(lp.upper.marginals)[:3]
    lower = np.asarray(lp.lower.marginals)[:3]
    boxes = np.ravel(np.c_[upper, lower])  # x_k <= box, then -x_k <= box
    ball = _checked(p, h, box, lp.x[:3], np.r_[y, boxes])
    if ball is None:
        return Ball(np.clip(lp.x[:3], -box, box), float((h - p @ lp.x[:3]).min()), math.inf, y)
    return ball
