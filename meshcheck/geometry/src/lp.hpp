// The largest ball in an intersection of half-spaces, a linear program in four variables:
//
//     maximise t  subject to  p_i . x + t <= h_i  (i < m)  and  -R <= x_k <= R  (k < 3).
//
// The verify stage solves thousands of these (the inradius of a convex hull, |p_i| = 1; one step
// of the inscribed-ball ascent), each with tens to hundreds of rows, where a general solver spends
// most of its time setting itself up. This is a dense simplex on the dual,
//
//     minimise h . y + R sum(w)  subject to  sum_i y_i (p_i, 1) + sum_k w_k (+-e_k, 0) = (0,0,0,1),
//     y, w >= 0,
//
// whose basis is four columns (four tight rows of the primal), so each iteration solves two 4x4
// systems and prices every row once. It starts from row 0 and the three box rows that cancel its
// normal (a feasible basis, no phase one), enters the most violated row (Bland's rule, the lowest
// index, after a run of steps that did not improve the objective, so it cannot cycle), and stops
// when no row is violated beyond a tolerance. Deterministic: no randomness, fixed order.
//
// The caller checks the answer (the centre's slack to every row against the bound the returned
// dual multipliers prove) and falls back to a general solver when the check fails.
#pragma once

#include <cmath>
#include <cstdint>
#include <utility>

#include "vec.hpp"

namespace meshcheck {

// Solve the 4x4 system M u = r by Gaussian elimination with partial pivoting (M row-major, both
// overwritten). False when a pivot is zero or not finite.
inline bool solve4(double M[4][4], double r[4], double u[4]) {
    for (int c = 0; c < 4; ++c) {
        int best = c;
        for (int i = c + 1; i < 4; ++i)
            if (std::fabs(M[i][c]) > std::fabs(M[best][c])) best = i;
        if (!(std::fabs(M[best][c]) > 0.0) || !std::isfinite(M[best][c])) return false;
        if (best != c) {
            for (int k = 0; k < 4; ++k) std::swap(M[c][k], M[best][k]);
            std::swap(r[c], r[best]);
        }
        for (int i = c + 1; i < 4; ++i) {
            double f = M[i][c] / M[c][c];
            for (int k = c; k < 4; ++k) M[i][k] -= f * M[c][k];
            r[i] -= f * r[c];
        }
    }
    for (int c = 3; c >= 0; --c) {
        double s = r[c];
        for (int k = c + 1; k < 4; ++k) s -= M[c][k] * u[k];
        u[c] = s / M[c][c];
        if (!std::isfinite(u[c])) return false;
    }
    return true;
}

// Row j of the primal as (a, rhs): j < m the given rows, then x_k <= R, -x_k <= R.
struct BallRows {
    const double* p;
    const double* h;
    int64_t m;
    double R;
    void get(int64_t j, double a[4], double& rhs) const {
        if (j < m) {
            a[0] = p[3 * j], a[1] = p[3 * j + 1], a[2] = p[3 * j + 2], a[3] = 1.0;
            rhs = h[j];
            return;
        }
        int64_t k = (j - m) / 2;
        a[0] = a[1] = a[2] = a[3] = 0.0;
        a[k] = ((j - m) % 2 == 0) ? 1.0 : -1.0;
        rhs = R;
    }
};

// Status of ball_lp.
constexpr int LP_OPTIMAL = 0, LP_ITERATIONS = 1, LP_FAILED = 2;

// Basic dual values y_B = B^-1 (0,0,0,1) and the primal vertex z (B^T z = h_B) of basis `basis`.
inline bool ball_basis(const BallRows& rows, const int64_t basis[4], double yb[4], double z[4]) {
    double B[4][4], BT[4][4], c[4] = {0.0, 0.0, 0.0, 1.0}, hb[4];
    for (int i = 0; i < 4; ++i) {
        double a[4];
        rows.get(basis[i], a, hb[i]);
        for (int k = 0; k < 4; ++k) B[k][i] = a[k], BT[i][k] = a[k];
    }
    return solve4(B, c, yb) && solve4(BT, hb, z);
}

// Maximise t (see the top of this file). Writes the optimal vertex x (3) and t, and the dual
// multipliers y (m + 6: rows, then x_0 <= R, -x_0 <= R, x_1 <= R, ...); returns a status.
inline int ball_lp(const double* p, const double* h, int64_t m, double R, int64_t max_iter,
                   double* x, double& t, double* y) {
    const int64_t n = m + 6;
    BallRows rows{p, h, m, R};
    for (int64_t j = 0; j < n; ++j) y[j] = 0.0;
    x[0] = x[1] = x[2] = 0.0, t = 0.0;
    if (m < 1 || !(R > 0.0) || !std::isfinite(R)) return LP_FAILED;
    double scale = R;
    for (int64_t i = 0; i < m; ++i) scale = std::fmax(scale, std::fabs(h[i]));
    if (!std::isfinite(scale)) return LP_FAILED;
    const double tol = 1e-13 * scale;
    // Row 0, and the box rows that cancel its normal: (p_0, 1) + sum |p_0k| (-sign p_0k e_k, 0).
    int64_t basis[4] = {0, 0, 0, 0};
    for (int k = 0; k < 3; ++k) basis[k + 1] = m + 2 * k + (p[k] > 0.0 ? 1 : 0);
    double yb[4], z[4];
    int stalled = 0;
    double objective = INF;
    for (int64_t iter = 0; iter < max_iter; ++iter) {
        if (!ball_basis(rows, basis, yb, z)) return LP_FAILED;
        double value = 0.0;
        for (int i = 0; i < 4; ++i) {
            double a[4], rhs;
            rows.get(basis[i], a, rhs);
            value += std::fmax(yb[i], 0.0) * rhs;
        }
        stalled = value < objective - tol ? 0 : stalled + 1;
        objective = std::fmin(objective, value);
        const bool bland = stalled > 8;
        // Entering: a violated row (most violated, or the first one when stalling).
        int64_t enter = -1;
        double worst = -tol;
        for (int64_t j = 0; j < n; ++j) {
            if (j == basis[0] || j == basis[1] || j == basis[2] || j == basis[3]) continue;
            double a[4], rhs;
            rows.get(j, a, rhs);
            double slack = rhs - (a[0] * z[0] + a[1] * z[1] + a[2] * z[2] + a[3] * z[3]);
            if (slack < worst) {
                enter = j, worst = slack;
                if (bland) break;
            }
        }
        if (enter < 0) {
            for (int i = 0; i < 4; ++i) y[basis[i]] = std::fmax(yb[i], 0.0);
            x[0] = z[0], x[1] = z[1], x[2] = z[2], t = z[3];
            return LP_OPTIMAL;
        }
        // Direction d = B^-1 a_enter; leaving: the least y_i / d_i over d_i > 0 (lowest row on a
        // tie, so the order is fixed).
        double B[4][4], a[4], rhs, d[4];
        rows.get(enter, a, rhs);
        for (int i = 0; i < 4; ++i) {
            double col[4], r;
            rows.get(basis[i], col, r);
            for (int k = 0; k < 4; ++k) B[k][i] = col[k];
        }
        if (!solve4(B, a, d)) return LP_FAILED;
        double dmax = 0.0;
        for (int i = 0; i < 4; ++i) dmax = std::fmax(dmax, std::fabs(d[i]));
        int leave = -1;
        double ratio = INF;
        for (int i = 0; i < 4; ++i) {
            if (d[i] <= 1e-12 * dmax) continue;
            double q = std::fmax(yb[i], 0.0) / d[i];
            if (q < ratio || (q == ratio && basis[i] < basis[leave])) leave = i, ratio = q;
        }
        if (leave < 0) return LP_FAILED;  // the dual is unbounded: no ball fits
        basis[leave] = enter;
    }
    return LP_ITERATIONS;
}

}  // namespace meshcheck
