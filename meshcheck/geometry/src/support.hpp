// Support maps: which vertex of a convex shape lies furthest along a direction.
//
// Small hulls are scanned; hulls with an adjacency (more than HILL_CLIMB_MIN_VERTICES vertices,
// see support.py) walk it from the previous answer. Every query works in re-centred
// coordinates: the caller passes the common centre c and gets the index of a vertex p
// maximising (p - c) . d. Subtracting before the dot product keeps the digits of shapes far
// from the origin.
#pragma once

#include "vec.hpp"

namespace meshcheck {

// One convex shape: its vertices pts[s0:s1] (rows of 3 doubles, global indices) and, when
// climb, the CSR vertex adjacency nbrs[nbr_starts[i]:nbr_starts[i + 1]].
struct Shape {
    const double* pts;
    const int64_t* nbr_starts;
    const int64_t* nbrs;
    int64_t s0, s1;
    bool climb;
};

inline double along(const double* pts, int64_t i, V3 d, const double* c) {
    const double* p = pts + 3 * i;
    return (p[0] - c[0]) * d.x + (p[1] - c[1]) * d.y + (p[2] - c[2]) * d.z;
}

// Index of a vertex of the shape maximising (p - c) . d; a walk starts at `start`.
inline int64_t support_index(const Shape& s, int64_t start, V3 d, const double* c) {
    if (s.climb) {
        int64_t best = start;
        double bv = along(s.pts, best, d, c);
        while (true) {
            int64_t nxt = best;
            for (int64_t e = s.nbr_starts[best]; e < s.nbr_starts[best + 1]; ++e) {
                int64_t j = s.nbrs[e];
                double val = along(s.pts, j, d, c);
                if (val > bv) bv = val, nxt = j;
            }
            if (nxt == best) return best;
            best = nxt;
        }
    }
    int64_t best = s.s0;
    double bv = -INF;
    for (int64_t i = s.s0; i < s.s1; ++i) {
        double val = along(s.pts, i, d, c);
        if (val > bv) bv = val, best = i;
    }
    return best;
}

// A point of the Minkowski difference A - B in re-centred coordinates, with its two sources
// (so witness points come for free) and their vertex indices.
struct CsoPoint {
    V3 w, a, b;
    int64_t ia, ib;
};

// Support point of A - B along d: s_A(d) - s_B(-d); walks start at start_a, start_b.
inline CsoPoint cso_support(const Shape& A, const Shape& B, const double* c, V3 d,
                            int64_t start_a, int64_t start_b) {
    CsoPoint p;
    p.ia = support_index(A, start_a, d, c);
    p.ib = support_index(B, start_b, {-d.x, -d.y, -d.z}, c);
    const double* pa = A.pts + 3 * p.ia;
    const double* pb = B.pts + 3 * p.ib;
    p.a = {pa[0] - c[0], pa[1] - c[1], pa[2] - c[2]};
    p.b = {pb[0] - c[0], pb[1] - c[1], pb[2] - c[2]};
    p.w = p.a - p.b;
    return p;
}

}  // namespace meshcheck
