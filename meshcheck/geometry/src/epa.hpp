// Penetration depth and normal: the Expanding Polytope Algorithm (EPA), and its entry from GJK.
//
// GJK hands over when the origin lies on or inside its simplex, i.e. the shapes meet. Then
//
// 1. the simplex is grown into a tetrahedron that holds the origin (one function per starting
//    size, grow_point / grow_segment / grow_triangle, as libccd's simplexToPolytope2/3/4),
//    checking on the way whether the Minkowski difference D = A - B is flat within the
//    tolerance in some direction: then the shapes only touch;
// 2. the polytope is expanded towards the boundary of D (epa). Each polytope lies inside D, so
//    its nearest face gives a *lower* bound on the depth; every support value h_D(n) gives an
//    *upper* bound. It stops on their gap, like GJK on the distance bounds.
#pragma once

#include <vector>

#include "gjk.hpp"

namespace meshcheck {

// Work space of one thread: the polytope gains one vertex per iteration (plus the 4-5 it
// starts with); a closed triangulated polytope has at most 2 V - 4 faces.
struct Polytope {
    int64_t max_verts, max_faces;
    std::vector<CsoPoint> v;
    std::vector<int64_t> fv;  // (max_faces, 3) vertex indices of each face
    std::vector<V3> fn;       // unit outward normals (0 for a degenerate face)
    std::vector<double> fd;   // plane offsets (inf for a degenerate face)
    std::vector<char> alive;
    std::vector<int64_t> free_faces;
    std::vector<int64_t> edges;  // (3 max_faces, 2) horizon edges

    Polytope()
        : max_verts(K.epa_max_iter + 8),
          max_faces(2 * max_verts),
          v(max_verts),
          fv(3 * max_faces),
          fn(max_faces),
          fd(max_faces),
          alive(max_faces),
          free_faces(max_faces),
          edges(6 * max_faces) {}
};

// One pair in contact: the shapes, their frame, and the answer being written.
struct Pair {
    const Shape& A;
    const Shape& B;
    const Frame& fr;
    Answer& out;
};

// Put the support point of A - B along d into row `slot`; return its value along d.
inline double support_into(const Pair& q, Polytope& P, V3 d, int64_t slot) {
    P.v[slot] = cso_support(q.A, q.B, q.fr.centre, d, P.v[0].ia, P.v[0].ib);
    const V3& w = P.v[slot].w;
    return w.x * d.x + w.y * d.y + w.z * d.z;
}

// Store face f = (i, j, k) with its unit normal and plane offset (inf if degenerate).
inline void set_face(Polytope& P, int64_t f, int64_t i, int64_t j, int64_t k) {
    P.fv[3 * f] = i, P.fv[3 * f + 1] = j, P.fv[3 * f + 2] = k;
    V3 ab = P.v[j].w - P.v[i].w, ac = P.v[k].w - P.v[i].w;
    V3 n = cross(ab, ac);
    double nn = std::sqrt(dot(n, n));
    double scale = std::sqrt(dot(ab, ab) * dot(ac, ac));
    if (nn <= K.degenerate_sin * scale || nn == 0.0) {
        P.fn[f] = {0.0, 0.0, 0.0};
        P.fd[f] = INF;
        return;
    }
    P.fn[f] = {n.x / nn, n.y / nn, n.z / nn};
    P.fd[f] = dot(n, P.v[i].w) / nn;
}

// Answer with the witness points of the point of face f nearest the origin.
inline void answer_face(const Pair& q, const Polytope& P, int status, double distance,
                        int64_t f, V3 n) {
    const CsoPoint& a = P.v[P.fv[3 * f]];
    const CsoPoint& b = P.v[P.fv[3 * f + 1]];
    const CsoPoint& c = P.v[P.fv[3 * f + 2]];
    double li, lj, lk;
    closest_on_triangle(ORIGIN, a.w, b.w, c.w, K.degenerate_sin, li, lj, lk);
    write_answer(q.out, status, distance, a.a * li + b.a * lj + c.a * lk,
                 a.b * li + b.b * lj + c.b * lk, n, q.fr.centre);
}

// -x for x > 0, else 0.0 (never -0.0): a depth bound as a signed distance.
inline double neg(double x) { return x > 0.0 ? -x : 0.0; }

// Expand the tetrahedron P.v[0:4] (holding the origin) to the depth of A - B.
//
// The depth is bracketed by `lower` (nearest face of the polytope, which lies inside D) and
// `upper` (least support value h_D(n) seen). The answer is TOUCHING when upper <= tol;
// PENETRATING when lower > tol (at once if not want_depth, with -lower); else the converged
// depth decides; on the iteration cap without a decision, UNDECIDED.
inline void epa(const Pair& q, Polytope& P, bool want_depth) {
    const double tol = q.fr.tol;
    const double zero_len = std::min(K.zero_rel * q.fr.size, 0.5 * tol);
    int64_t nv = 4;

    // Start faces, turned so their normals point away from the centroid (an interior point).
    V3 g{0.25 * (P.v[0].w.x + P.v[1].w.x + P.v[2].w.x + P.v[3].w.x),
         0.25 * (P.v[0].w.y + P.v[1].w.y + P.v[2].w.y + P.v[3].w.y),
         0.25 * (P.v[0].w.z + P.v[1].w.z + P.v[2].w.z + P.v[3].w.z)};
    static constexpr int START[4][3] = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
    for (int f = 0; f < 4; ++f) {
        int i = START[f][0], j = START[f][1], k = START[f][2];
        V3 o = g - P.v[i].w;
        V3 ab = P.v[j].w - P.v[i].w, ac = P.v[k].w - P.v[i].w;
        if (dot(o, cross(ab, ac)) > 0.0) std::swap(j, k);
        set_face(P, f, i, j, k);
        P.alive[f] = 1;
    }
    int64_t nf = 4, nfree = 0;

    double lower = -INF, upper = INF;
    V3 u{1.0, 0.0, 0.0};
    int64_t best = -1;
    for (int64_t it = 0; it < K.epa_max_iter; ++it) {
        best = -1;
        double dmin = INF;
        for (int64_t f = 0; f < nf; ++f) {
            if (P.alive[f] && P.fd[f] < dmin) dmin = P.fd[f], best = f;
        }
        if (best < 0) break;
        if (dmin > lower) lower = dmin;
        V3 n = P.fn[best];
        if (!want_depth && lower > tol) {
            answer_face(q, P, K.penetrating, -lower, best, n);
            return;
        }
        if (nv >= P.max_verts) break;
        double h = support_into(q, P, n, nv);
        if (h < upper) upper = h, u = n;
        if (upper <= tol) {
            answer_face(q, P, K.touching, neg(upper), best, u);
            return;
        }
        bool converged = h - dmin <= K.epa_rel_gap * std::fabs(h) + zero_len;
        if (!converged) {
            for (int64_t r = 0; r < nv; ++r) {
                if (P.v[r].ia == P.v[nv].ia && P.v[r].ib == P.v[nv].ib) {
                    converged = true;
                    break;
                }
            }
        }
        if (converged) {
            int status = dmin > tol ? K.penetrating : K.touching;
            answer_face(q, P, status, -dmin, best, n);
            return;
        }
        // Remove the faces the new point sees; their outline (the horizon) is kept as the
        // directed edges whose reverse is not also removed.
        V3 w = P.v[nv].w;
        int64_t ne = 0;
        for (int64_t f = 0; f < nf; ++f) {
            if (!P.alive[f]) continue;
            if (f != best && dot(P.fn[f], w) - P.fd[f] <= zero_len) continue;
            P.alive[f] = 0;
            P.free_faces[nfree++] = f;
            for (int e = 0; e < 3; ++e) {
                int64_t p = P.fv[3 * f + e], r = P.fv[3 * f + (e + 1) % 3];
                int64_t found = -1;
                for (int64_t s = 0; s < ne; ++s) {
                    if (P.edges[2 * s] == r && P.edges[2 * s + 1] == p) {
                        found = s;
                        break;
                    }
                }
                if (found >= 0) {
                    --ne;
                    P.edges[2 * found] = P.edges[2 * ne];
                    P.edges[2 * found + 1] = P.edges[2 * ne + 1];
                } else {
                    P.edges[2 * ne] = p;
                    P.edges[2 * ne + 1] = r;
                    ++ne;
                }
            }
        }
        for (int64_t s = 0; s < ne; ++s) {
            int64_t f = nfree > 0 ? P.free_faces[--nfree] : nf++;
            set_face(P, f, P.edges[2 * s], P.edges[2 * s + 1], nv);
            P.alive[f] = 1;
        }
        ++nv;
    }

    // Iteration cap (or numerical trouble): decide from the bounds where they allow it.
    if (best < 0) {
        write_answer(q.out, K.undecided, 0.0, ORIGIN, ORIGIN, u, q.fr.centre);
    } else if (lower > tol) {
        answer_face(q, P, K.penetrating, -lower, best, P.fn[best]);
    } else if (upper <= tol) {
        answer_face(q, P, K.touching, neg(upper), best, u);
    } else {
        answer_face(q, P, K.undecided, neg(lower), best, u);
    }
}

// ---------------------------------------------------------------------------------------------
// From the GJK simplex to a tetrahedron holding the origin. Before each new point, the support
// value along its direction says whether D is flat there within tol: then the origin is within
// tol of D's boundary and the shapes only touch. Each function returns the new number of
// polytope vertices, or 0 when it has written the answer. (pa, pb): where GJK found the origin,
// the witness points of a touching answer.

// One point: find a second one off it along an axis.
inline int grow_point(const Pair& q, Polytope& P, V3 pa, V3 pb) {
    const double zero_len = K.zero_rel * q.fr.size;
    for (int axis = 0; axis < 6; ++axis) {
        double sign = axis < 3 ? 1.0 : -1.0;
        V3 d{axis % 3 == 0 ? sign : 0.0, axis % 3 == 1 ? sign : 0.0, axis % 3 == 2 ? sign : 0.0};
        double h = support_into(q, P, d, 1);
        if (h <= q.fr.tol) {
            write_answer(q.out, K.touching, 0.0, pa, pb, d, q.fr.centre);
            return 0;
        }
        if (h - dot(P.v[0].w, d) > zero_len) return 2;
    }
    write_answer(q.out, K.undecided, 0.0, pa, pb, {1.0, 0.0, 0.0}, q.fr.centre);
    return 0;
}

// A segment: two directions square to it (cross it with its least-aligned axis, then with
// that); keep the support point that stands furthest off the segment's line. A segment of
// zero length falls back to its first point.
inline int grow_segment(const Pair& q, Polytope& P, V3 pa, V3 pb) {
    V3 e = P.v[1].w - P.v[0].w;
    double el = std::sqrt(dot(e, e));
    if (el <= K.zero_rel * q.fr.size) return 1;
    double ax = std::fabs(e.x), ay = std::fabs(e.y), az = std::fabs(e.z);
    V3 u;
    if (ax <= ay && ax <= az) {
        u = {0.0, e.z, -e.y};
    } else if (ay <= az) {
        u = {-e.z, 0.0, e.x};
    } else {
        u = {e.y, -e.x, 0.0};
    }
    double ul = std::sqrt(dot(u, u));
    u = {u.x / ul, u.y / ul, u.z / ul};
    double first_h = 0.0;
    for (int turn = 0; turn < 2; ++turn) {
        if (turn == 1) {
            V3 c = cross(e, u);
            u = {c.x / el, c.y / el, c.z / el};
        }
        double h = support_into(q, P, u, 2 + turn);
        if (h <= q.fr.tol) {
            write_answer(q.out, K.touching, 0.0, pa, pb, u, q.fr.centre);
            return 0;
        }
        if (turn == 0) {
            first_h = h;
        } else if (h > first_h) {
            P.v[2] = P.v[3];
        }
    }
    return 3;
}

// A triangle: the support points on both sides of its plane (the +n one stays in row 3). A
// needle triangle keeps its longest edge (the origin lies on it) and falls back to a segment.
inline int grow_triangle(const Pair& q, Polytope& P, V3 pa, V3 pb) {
    V3 ab = P.v[1].w - P.v[0].w, ac = P.v[2].w - P.v[0].w;
    V3 n = cross(ab, ac);
    double nn = std::sqrt(dot(n, n));
    double lab = std::sqrt(dot(ab, ab)), lac = std::sqrt(dot(ac, ac));
    if (nn <= K.degenerate_sin * lab * lac || nn == 0.0) {
        double lbc = std::sqrt(dist2(P.v[1].w, P.v[2].w));
        int drop = (lab >= lac && lab >= lbc) ? 2 : (lac >= lbc ? 1 : 0);
        for (int r = drop; r < 2; ++r) P.v[r] = P.v[r + 1];
        return 2;
    }
    n = {n.x / nn, n.y / nn, n.z / nn};
    for (double side : {-1.0, 1.0}) {
        V3 d = n * side;
        double h = support_into(q, P, d, 3);
        if (h <= q.fr.tol) {
            write_answer(q.out, K.touching, 0.0, pa, pb, d, q.fr.centre);
            return 0;
        }
    }
    return 4;
}

// Classify and measure a pair whose GJK simplex (k points, 1 to 4) holds the origin: with
// k < 4 the origin lies on the simplex (within rounding or tol); with k == 4 the tetrahedron
// encloses it. If not want_depth, stop as soon as the status is known: a PENETRATING answer
// then carries minus a lower bound of the depth.
inline void contact(const Pair& q, const Simplex& s, int k, bool want_depth, Polytope& P) {
    V3 pa, pb;
    simplex_witnesses(s, k, pa, pb);
    for (int r = 0; r < k; ++r) P.v[r] = s.p[r];
    int nv = k;
    for (int passes = 1; nv < 4; ++passes) {
        if (passes > 8) {
            // Needle triangles again and again: no tetrahedron can be built.
            write_answer(q.out, K.undecided, 0.0, pa, pb, {1.0, 0.0, 0.0}, q.fr.centre);
            return;
        }
        if (nv == 1) {
            nv = grow_point(q, P, pa, pb);
        } else if (nv == 2) {
            nv = grow_segment(q, P, pa, pb);
        } else {
            nv = grow_triangle(q, P, pa, pb);
        }
        if (nv == 0) return;
    }
    epa(q, P, want_depth);
}

}  // namespace meshcheck
