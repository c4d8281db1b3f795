// GJK on one pair of convex shapes: status, distance and witness points, or the simplex that
// holds the origin for EPA (see gjk.py for the method and its bounds).
#pragma once

#include <algorithm>

#include "simplex.hpp"

namespace meshcheck {

// Common frame of one query: the centre both shapes are re-centred on, the first search
// direction (from A toward B), the size (largest AABB edge) and the tolerance.
struct Frame {
    double centre[3];
    V3 guess;
    double size, tol;
};

// Fill the frame from the AABBs (lo_a, hi_a, lo_b, hi_b); tol < 0 means the default tolerance.
inline Frame make_frame(const double* lo_a, const double* hi_a, const double* lo_b,
                        const double* hi_b, double tol) {
    Frame f;
    double size = 0.0, coord = 0.0, gl = 0.0, g[3];
    for (int c = 0; c < 3; ++c) {
        double ca = 0.5 * (lo_a[c] + hi_a[c]);
        double cb = 0.5 * (lo_b[c] + hi_b[c]);
        f.centre[c] = 0.5 * (ca + cb);
        g[c] = cb - ca;
        gl += g[c] * g[c];
        size = std::max({size, hi_a[c] - lo_a[c], hi_b[c] - lo_b[c]});
        coord = std::max({coord, std::fabs(lo_a[c]), std::fabs(hi_a[c]), std::fabs(lo_b[c]),
                          std::fabs(hi_b[c])});
    }
    f.guess = gl == 0.0 ? V3{1.0, 0.0, 0.0} : V3{g[0], g[1], g[2]};
    if (tol < 0.0) tol = std::max(K.touch_rel * size, K.coord_rel * coord);
    f.size = size;
    f.tol = tol;
    return f;
}

inline void answer_simplex(Answer& out, int status, double distance, const Simplex& s, int k,
                           V3 n, const double* centre) {
    V3 a, b;
    simplex_witnesses(s, k, a, b);
    write_answer(out, status, distance, a, b, n, centre);
}

// Run GJK on one pair. Returns 0 when `out` holds the answer; else the size of the simplex `s`
// that holds the origin (the shapes meet), for contact() in epa.hpp. Stops with SEPARATED as
// soon as the distance is known to exceed max_distance (and tol); the distance is then that
// lower bound.
inline int gjk(const Shape& A, const Shape& B, const Frame& fr, double max_distance, Simplex& s,
               Answer& out) {
    const double* centre = fr.centre;
    const double tol = fr.tol;
    const double zero_eps = std::min(K.zero_rel * fr.size, 0.5 * tol);
    s.p[0] = cso_support(A, B, centre, fr.guess, A.s0, B.s0);
    s.lam[0] = 1.0;
    int64_t ia = s.p[0].ia, ib = s.p[0].ib;  // the last support points: where walks start
    int k = 1;
    V3 v = s.p[0].w;
    double lower = -INF;
    double upper = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);

    for (int64_t it = 0; it < K.gjk_max_iter; ++it) {
        if (upper <= zero_eps) return k;  // the origin is on the simplex: the shapes meet
        CsoPoint w = cso_support(A, B, centre, {-v.x, -v.y, -v.z}, ia, ib);
        ia = w.ia, ib = w.ib;
        double lb = (w.w.x * v.x + w.w.y * v.y + w.w.z * v.z) / upper;
        if (lb > lower) lower = lb;
        if (lower > tol && lower > max_distance) {
            answer_simplex(out, K.separated, lower, s, k, {-v.x, -v.y, -v.z}, centre);
            return 0;
        }
        if (upper - lower <= K.gjk_rel_gap * upper) break;  // converged
        if (upper <= tol && lower >= -tol) break;  // touching, on the word of a fresh support
        bool repeated = false;
        for (int r = 0; r < k; ++r)
            if (s.p[r].ia == w.ia && s.p[r].ib == w.ib) repeated = true;
        if (repeated) break;  // no new point: converged up to rounding
        s.p[k] = w;
        ++k;
        if (k == 2) {
            k = do_simplex2(s);
        } else if (k == 3) {
            k = do_simplex3(s);
        } else {
            bool encloses;
            k = do_simplex4(s, encloses);
            if (encloses) return k;  // the tetrahedron holds the origin: the shapes meet
        }
        v = nearest_point(s, k);
        double new_upper = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        bool stalled = new_upper >= upper;
        upper = new_upper;
        if (stalled) break;  // no progress (rounding): decide from the bounds
    }

    int status;
    double distance;
    if (lower > tol) {
        status = K.separated;
        distance = upper;
    } else if (upper <= tol && lower >= -tol) {
        status = K.touching;
        distance = lower >= 0.0 ? upper : 0.0;
    } else if (upper - lower <= K.gjk_rel_gap * upper) {
        // Converged, with the tolerance inside the (tiny) bracket: the estimate decides.
        status = upper > tol ? K.separated : K.touching;
        distance = upper;
    } else if (upper <= tol) {
        // The origin is within tol of the simplex but no direction has shown the far side of
        // D within tol (a flat or sliver D). Let the blow-up and EPA look for one: their
        // TOUCHING / PENETRATING verdicts rest on bounds that hold wherever the origin is.
        return k;
    } else {
        status = K.undecided;
        distance = std::isfinite(lower) ? lower : 0.0;
    }
    answer_simplex(out, status, distance, s, k, {-v.x, -v.y, -v.z}, centre);
    return 0;
}

}  // namespace meshcheck
