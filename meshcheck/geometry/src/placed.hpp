// Distances between two packs of convex pieces at many rigid placements of the second in the
// first's frame: the sweep's question (is a box of joint values clear?), asked of every box
// centre of a batch in one call without building a pack per placement (see gjk.py,
// placed_distances, for the bounds this returns).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "epa.hpp"
#include "triangles.hpp"

namespace meshcheck {

// One pack of pieces: points (rows of 3), piece ranges `starts`, the hull adjacency (CSR) and,
// for the fixed pack, each piece's box.
struct Pieces {
    const double* points;
    const int64_t *starts, *nbr_starts, *nbrs;
    const double *lower, *upper;
    int64_t m;  // pieces
    int64_t n;  // points
};

struct PlacedBatch {
    Pieces a, b;
    const double* relative;  // (E, 4, 4): b's frame into a's
    const double *pad_a, *pad_b, *reach;
    bool settle;
    double* lowest;  // (E,)
};

// What a batch cost: GJK queries run, piece boxes compared and, for copied pieces, the
// copies the queries' supports scanned (summed over queries).
struct PlacedWorkDone {
    int64_t queries = 0, boxes = 0, supports = 0;
};

// Work space of one placement: b's points placed, their pieces' boxes, candidate pairs.
struct PlacedWork {
    std::vector<double> points, lower, upper;
    std::vector<int64_t> cand_i, cand_j;
    std::vector<double> cand_key;
    std::vector<char> cand_apart;  // the boxes do not overlap
    std::vector<size_t> order;
    Simplex s;
    Polytope P;
};

// The piece pairs (i, j) whose boxes (a's m_a boxes against b's m_b, (m, 3) corners each)
// come within reach of each other less both pads, into work's candidates with that gap.
inline void box_candidates(const double* lower_a, const double* upper_a, int64_t m_a,
                           const double* lower_b, const double* upper_b, int64_t m_b,
                           const double* pad_a, const double* pad_b, double reach,
                           PlacedWork& w) {
    w.cand_i.clear(), w.cand_j.clear(), w.cand_key.clear(), w.cand_apart.clear();
    for (int64_t i = 0; i < m_a; ++i) {
        const double* la = lower_a + 3 * i;
        const double* ua = upper_a + 3 * i;
        for (int64_t j = 0; j < m_b; ++j) {
            const double* lb = lower_b + 3 * j;
            const double* ub = upper_b + 3 * j;
            double sq = 0.0;
            for (int c = 0; c < 3; ++c) {
                double g = std::max({la[c] - ub[c], lb[c] - ua[c], 0.0});
                sq += g * g;
            }
            double key = std::sqrt(sq) - (pad_a[i] + pad_b[j]);
            if (key <= reach) {
                w.cand_i.push_back(i);
                w.cand_j.push_back(j);
                w.cand_key.push_back(key);
                w.cand_apart.push_back(sq > 0.0);
            }
        }
    }
}

// Lower bound on the distance of piece i of a and piece j of b (b already placed in work),
// less both pads: GJK stops once it is past reach + pad; an undecided answer counts as 0 or
// its (negative) bound.
inline double piece_gap(const PlacedBatch& t, PlacedWork& w, int64_t i, int64_t j,
                        double reach, PlacedWorkDone& done) {
    ++done.queries;
    const Pieces &a = t.a, &b = t.b;
    int64_t a0 = a.starts[i], a1 = a.starts[i + 1], b0 = b.starts[j], b1 = b.starts[j + 1];
    Shape A{a.points, a.nbr_starts, a.nbrs, a0, a1, a.nbr_starts[a0 + 1] > a.nbr_starts[a0]};
    Shape B{w.points.data(), b.nbr_starts, b.nbrs, b0, b1,
            b.nbr_starts[b0 + 1] > b.nbr_starts[b0]};
    Frame fr = make_frame(a.lower + 3 * i, a.upper + 3 * i, w.lower.data() + 3 * j,
                          w.upper.data() + 3 * j, 0.0);
    double pad = t.pad_a[i] + t.pad_b[j];
    Answer out;
    int k = gjk(A, B, fr, reach + pad, w.s, out);
    if (k > 0) contact(Pair{A, B, fr, out}, w.s, k, false, w.P);
    double d = out.v[1];
    if (static_cast<int>(out.v[0]) == K.undecided) d = std::min(d, 0.0);
    return d - pad;
}

// Place b's points by the placement's (4, 4) transform and bound each of its pieces; false
// when the transform is not finite.
inline bool place_pieces(const Pieces& b, const double* T, PlacedWork& w) {
    for (int c = 0; c < 12; ++c)
        if (!std::isfinite(T[c])) return false;
    w.points.resize(3 * b.n);
    w.lower.resize(3 * b.m);
    w.upper.resize(3 * b.m);
    for (int64_t p = 0; p < b.n; ++p) {
        const double* q = b.points + 3 * p;
        double* o = w.points.data() + 3 * p;
        for (int r = 0; r < 3; ++r)
            o[r] = q[0] * T[4 * r] + q[1] * T[4 * r + 1] + q[2] * T[4 * r + 2] + T[4 * r + 3];
    }
    for (int64_t s = 0; s < b.m; ++s) {
        double* lo = w.lower.data() + 3 * s;
        double* hi = w.upper.data() + 3 * s;
        for (int c = 0; c < 3; ++c) lo[c] = INF, hi[c] = -INF;
        for (int64_t p = b.starts[s]; p < b.starts[s + 1]; ++p) {
            for (int c = 0; c < 3; ++c) {
                double x = w.points[3 * p + c];
                lo[c] = std::min(lo[c], x);
                hi[c] = std::max(hi[c], x);
            }
        }
    }
    return true;
}

// Placement e: the least piece gap among the piece pairs whose boxes come within reach (plus
// their pads), inf when none does. Pairs are measured nearest boxes first, each GJK stopping
// past the least gap so far (when not negative; else reach), and no pair whose boxes are apart
// by no less than that gap is measured: boxes apart bound the pieces' distance from below, so
// the least is the same. With settle, the first pair that comes within reach answers alone.
inline double placed_distance(const PlacedBatch& t, int64_t e, PlacedWork& w,
                              PlacedWorkDone& done) {
    const double reach = t.reach[e];
    if (!place_pieces(t.b, t.relative + 16 * e, w) || std::isnan(reach)) return -INF;
    box_candidates(t.a.lower, t.a.upper, t.a.m, w.lower.data(), w.upper.data(), t.b.m, t.pad_a,
                   t.pad_b, reach, w);
    done.boxes += t.a.m * t.b.m;
    size_t count = w.cand_i.size();
    if (count == 0) return INF;
    w.order.resize(count);
    for (size_t c = 0; c < count; ++c) w.order[c] = c;
    std::stable_sort(w.order.begin(), w.order.end(),
                     [&](size_t x, size_t y) { return w.cand_key[x] < w.cand_key[y]; });
    double lowest = INF;
    for (size_t c : w.order) {
        int64_t i = w.cand_i[c], j = w.cand_j[c];
        // boxes apart bound the pieces' distance from below; overlapping boxes bound nothing
        // of a depth
        if (w.cand_apart[c] && w.cand_key[c] >= lowest) continue;
        double stop = lowest >= 0.0 ? std::min(reach, lowest) : reach;
        lowest = std::min(lowest, piece_gap(t, w, i, j, stop, done));
        if (t.settle && lowest <= reach) break;
    }
    return lowest;
}

inline PlacedWorkDone placed_distances(const PlacedBatch& t, int64_t count) {
    PlacedWork w;
    PlacedWorkDone done;
    for (int64_t e = 0; e < count; ++e) t.lowest[e] = placed_distance(t, e, w, done);
    return done;
}

}  // namespace meshcheck

namespace meshcheck {

// A kinematic chain's last link at `count` poses: for each of its `joints` movable joints, the
// fixed transform before it (`before[j]`, (4, 4): its origin and any fixed joints since the
// previous movable one), then its motion at `values[e, j]`: a turn by that angle about the unit
// `axes[j]` (Rodrigues: I + sin K + (1 - cos) K K, K the axis's cross matrix) when `kinds[j]`
// is 0, a slide along it by that length when 1; `after` (4, 4) closes the chain. Lengths are
// the chain's own; `out[e]` (4, 4) has its translation times `scale`, and `points[e, j]`
// (times `scale`) and `directions[e, j]` are joint j's axis line at pose e, in the chain's
// root frame.
inline void chain_placements(const double* before, const int64_t* kinds, const double* axes,
                             const double* after, const double* values, int64_t count,
                             int64_t joints, double scale, double* out, double* points,
                             double* directions) {
    // Rigid motions as their top three rows (3, 4): z = x y, summed in the order a (4, 4)
    // product would (its bottom row 0 0 0 1 adds only exact zeros and ones).
    auto times = [](const double* x, const double* y, double* z) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)
                z[4 * r + c] = x[4 * r] * y[c] + x[4 * r + 1] * y[4 + c] + x[4 * r + 2] * y[8 + c];
            z[4 * r + 3] = x[4 * r] * y[3] + x[4 * r + 1] * y[7] + x[4 * r + 2] * y[11] +
                           x[4 * r + 3];
        }
    };
    std::vector<double> squares(9 * joints);  // K K of each turning joint's cross matrix K
    for (int64_t j = 0; j < joints; ++j) {
        const double* u = axes + 3 * j;
        const double K[9] = {0.0, -u[2], u[1], u[2], 0.0, -u[0], -u[1], u[0], 0.0};
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k)
                squares[9 * j + 3 * r + k] =
                    K[3 * r] * K[k] + K[3 * r + 1] * K[3 + k] + K[3 * r + 2] * K[6 + k];
    }
    for (int64_t e = 0; e < count; ++e) {
        double placed[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}, next[12];
        for (int64_t j = 0; j < joints; ++j) {
            times(placed, before + 16 * j, next);
            const double* u = axes + 3 * j;
            double* point = points + 3 * (e * joints + j);
            double* direction = directions + 3 * (e * joints + j);
            for (int r = 0; r < 3; ++r) {
                point[r] = next[4 * r + 3] * scale;
                direction[r] = next[4 * r] * u[0] + next[4 * r + 1] * u[1] + next[4 * r + 2] * u[2];
            }
            const double q = values[e * joints + j];
            double motion[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
            if (kinds[j] == 1) {
                for (int r = 0; r < 3; ++r) motion[4 * r + 3] = q * u[r];
            } else {
                const double K[9] = {0.0, -u[2], u[1], u[2], 0.0, -u[0], -u[1], u[0], 0.0};
                const double* kk = &squares[9 * j];
                const double s = std::sin(q), c = 1.0 - std::cos(q);
                for (int r = 0; r < 3; ++r)
                    for (int k = 0; k < 3; ++k)
                        motion[4 * r + k] =
                            (r == k ? 1.0 : 0.0) + s * K[3 * r + k] + c * kk[3 * r + k];
            }
            times(next, motion, placed);
        }
        double* T = out + 16 * e;
        times(placed, after, T);
        for (int r = 0; r < 3; ++r) T[4 * r + 3] *= scale;
        T[12] = T[13] = T[14] = 0.0;
        T[15] = 1.0;
    }
}

// levers[e, t]: the largest distance of the hull points (k rows, a link's frame), placed by
// placed[e] (4, 4), from the line through points[e, t] along the unit directions[e, t].
inline void hull_levers(const double* hull, int64_t k, const double* placed, const double* points,
                        const double* directions, int64_t count, int64_t lines, double* levers) {
    std::vector<double> posed(3 * k);
    for (int64_t e = 0; e < count; ++e) {
        const double* T = placed + 16 * e;
        for (int64_t p = 0; p < k; ++p) {
            const double* q = hull + 3 * p;
            for (int r = 0; r < 3; ++r)
                posed[3 * p + r] =
                    q[0] * T[4 * r] + q[1] * T[4 * r + 1] + q[2] * T[4 * r + 2] + T[4 * r + 3];
        }
        for (int64_t t = 0; t < lines; ++t) {
            const double* o = points + 3 * (e * lines + t);
            const double* u = directions + 3 * (e * lines + t);
            double worst = 0.0;
            for (int64_t p = 0; p < k; ++p) {
                double d[3] = {posed[3 * p] - o[0], posed[3 * p + 1] - o[1],
                               posed[3 * p + 2] - o[2]};
                double along = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
                double sq = 0.0;
                for (int c = 0; c < 3; ++c) {
                    double off = d[c] - along * u[c];
                    sq += off * off;
                }
                if (std::isnan(sq)) worst = INF;  // never a lever too short
                worst = std::max(worst, sq);
            }
            levers[e * lines + t] = std::sqrt(worst);
        }
    }
}

}  // namespace meshcheck

namespace meshcheck {

// The triangle pairs of two meshes, b placed in a's frame by T (4, 4), whose boxes come within
// reach of each other along every axis: only a's triangles near b's whole box, and b's near
// theirs, are paired (box_pairs, a hierarchy over b's). `pairs` gets (face of a, face of b);
// `placed` b's vertices in a's frame; `alo`..`bhi` every triangle's box (b's placed).
struct NearTriangles {
    std::vector<double> placed, alo, ahi, blo, bhi;
    std::vector<int64_t> pairs;
};

inline void near_triangle_pairs(const double* va, const int64_t* fa, int64_t ma,
                                const double* vb, int64_t nb, const int64_t* fb, int64_t mb,
                                const double* T, double reach, NearTriangles& out) {
    out.placed.resize(3 * nb);
    for (int64_t p = 0; p < nb; ++p) {
        const double* q = vb + 3 * p;
        for (int r = 0; r < 3; ++r)
            out.placed[3 * p + r] =
                q[0] * T[4 * r] + q[1] * T[4 * r + 1] + q[2] * T[4 * r + 2] + T[4 * r + 3];
    }
    out.alo.resize(3 * ma), out.ahi.resize(3 * ma), out.blo.resize(3 * mb), out.bhi.resize(3 * mb);
    triangle_boxes(va, fa, ma, out.alo.data(), out.ahi.data());
    triangle_boxes(out.placed.data(), fb, mb, out.blo.data(), out.bhi.data());
    out.pairs.clear();
    auto span = [](const std::vector<double>& lo, const std::vector<double>& hi,
                   const std::vector<int64_t>& rows, double* slo, double* shi) {
        for (int c = 0; c < 3; ++c) slo[c] = INF, shi[c] = -INF;
        for (int64_t k : rows)
            for (int c = 0; c < 3; ++c) {
                slo[c] = std::min(slo[c], lo[3 * k + c]);
                shi[c] = std::max(shi[c], hi[3 * k + c]);
            }
    };
    std::vector<int64_t> all_b(mb), near_a, near_b;
    for (int64_t j = 0; j < mb; ++j) all_b[j] = j;
    double slo[3], shi[3];
    span(out.blo, out.bhi, all_b, slo, shi);
    for (int64_t i = 0; i < ma; ++i)
        if (boxes_near(&out.alo[3 * i], &out.ahi[3 * i], slo, shi, reach)) near_a.push_back(i);
    span(out.alo, out.ahi, near_a, slo, shi);
    for (int64_t j = 0; j < mb; ++j)
        if (boxes_near(&out.blo[3 * j], &out.bhi[3 * j], slo, shi, reach)) near_b.push_back(j);
    if (near_a.empty() || near_b.empty()) return;
    auto boxes_of = [](const std::vector<double>& lo, const std::vector<double>& hi,
                       const std::vector<int64_t>& rows, std::vector<double>& slo,
                       std::vector<double>& shi) {
        slo.resize(3 * rows.size()), shi.resize(3 * rows.size());
        for (size_t k = 0; k < rows.size(); ++k)
            for (int c = 0; c < 3; ++c) {
                slo[3 * k + c] = lo[3 * rows[k] + c];
                shi[3 * k + c] = hi[3 * rows[k] + c];
            }
    };
    std::vector<double> plo, phi, clo, chi;
    boxes_of(out.alo, out.ahi, near_a, plo, phi);
    boxes_of(out.blo, out.bhi, near_b, clo, chi);
    box_pairs(plo.data(), phi.data(), static_cast<int64_t>(near_a.size()), clo.data(),
              chi.data(), static_cast<int64_t>(near_b.size()), reach, out.pairs);
    for (size_t q = 0; q < out.pairs.size(); q += 2) {
        out.pairs[q] = near_a[out.pairs[q]];
        out.pairs[q + 1] = near_b[out.pairs[q + 1]];
    }
}

// The distance between two meshes, b placed in a's frame by T (4, 4), exact when at most
// reach (else a value above it, inf when no triangle pair's boxes come within reach): the
// triangle pairs near each other (near_triangle_pairs) are measured nearest boxes first. With
// settle, the first pair within reach answers. `work` gets the triangle pairs measured.
inline double placed_surface_distance(const double* va, const int64_t* fa, int64_t ma,
                                      const double* vb, int64_t nb, const int64_t* fb,
                                      int64_t mb, const double* T, double reach, bool settle,
                                      int64_t& work) {
    for (int c = 0; c < 12; ++c)
        if (!std::isfinite(T[c])) return -INF;
    if (std::isnan(reach)) return -INF;
    NearTriangles near;
    near_triangle_pairs(va, fa, ma, vb, nb, fb, mb, T, reach, near);
    const std::vector<int64_t>& pairs = near.pairs;
    size_t count = pairs.size() / 2;
    if (count == 0) return INF;
    std::vector<double> gap(count);
    std::vector<size_t> order(count);
    for (size_t q = 0; q < count; ++q) {
        const double* l0 = &near.alo[3 * pairs[2 * q]];
        const double* h0 = &near.ahi[3 * pairs[2 * q]];
        const double* l1 = &near.blo[3 * pairs[2 * q + 1]];
        const double* h1 = &near.bhi[3 * pairs[2 * q + 1]];
        double sq = 0.0;
        for (int c = 0; c < 3; ++c) {
            double g = std::max({l0[c] - h1[c], l1[c] - h0[c], 0.0});
            sq += g * g;
        }
        gap[q] = sq;
        order[q] = q;
    }
    if (settle)
        std::stable_sort(order.begin(), order.end(),
                         [&](size_t x, size_t y) { return gap[x] < gap[y]; });
    double best = INF;
    for (size_t q : order) {
        Tri ta = triangle(va, fa, pairs[2 * q]);
        Tri tb = triangle(near.placed.data(), fb, pairs[2 * q + 1]);
        V3 x, y;
        bool crossing;
        double d = triangle_distance(ta, tb, x, y, crossing);
        ++work;
        best = std::min(best, d);
        if (settle && best <= reach) break;
    }
    return best;
}

}  // namespace meshcheck

namespace meshcheck {

// Many copies of one pack of pieces, each piece's copies held as one point set: the hull of
// piece i's copies under K placements. Piece i's copies are rows [K * starts[i], K *
// starts[i + 1]) of `points`, placed only once the piece is wanted; no adjacency (the
// support scans them). Each piece's box holds its copies' boxes.
struct CopiedPieces {
    std::vector<double> points, lower, upper;
    std::vector<char> placed;
};

// Bound `count` copies of pack p's pieces (its boxes placed by the (4, 4) transforms T); false
// when a transform is not finite.
inline bool bound_copies(const Pieces& p, const double* T, int64_t count, CopiedPieces& out) {
    for (int64_t k = 0; k < count; ++k)
        for (int c = 0; c < 12; ++c)
            if (!std::isfinite(T[16 * k + c])) return false;
    out.points.resize(3 * p.n * count);
    out.lower.assign(3 * p.m, INF);
    out.upper.assign(3 * p.m, -INF);
    out.placed.assign(p.m, 0);
    for (int64_t s = 0; s < p.m; ++s) {
        const double* lo = p.lower + 3 * s;
        const double* hi = p.upper + 3 * s;
        for (int64_t k = 0; k < count; ++k) {
            const double* M = T + 16 * k;
            for (int r = 0; r < 3; ++r) {
                double mid = M[4 * r + 3], ext = 0.0;
                for (int c = 0; c < 3; ++c) {
                    mid += M[4 * r + c] * 0.5 * (lo[c] + hi[c]);
                    ext += std::fabs(M[4 * r + c]) * 0.5 * (hi[c] - lo[c]);
                }
                out.lower[3 * s + r] = std::min(out.lower[3 * s + r], mid - ext);
                out.upper[3 * s + r] = std::max(out.upper[3 * s + r], mid + ext);
            }
        }
    }
    return true;
}

// Place the `count` copies of piece s of pack p (once).
inline void place_copies(const Pieces& p, const double* T, int64_t count, int64_t s,
                         CopiedPieces& out) {
    if (out.placed[s]) return;
    out.placed[s] = 1;
    int64_t s0 = p.starts[s], s1 = p.starts[s + 1];
    double* o = out.points.data() + 3 * count * s0;
    for (int64_t k = 0; k < count; ++k) {
        const double* M = T + 16 * k;
        for (int64_t q = s0; q < s1; ++q, o += 3) {
            const double* x = p.points + 3 * q;
            for (int r = 0; r < 3; ++r)
                o[r] = x[0] * M[4 * r] + x[1] * M[4 * r + 1] + x[2] * M[4 * r + 2] + M[4 * r + 3];
        }
    }
}

struct CopiedBatch {
    Pieces a, b;
    const double *ca, *cb;  // (E, 4, 4): one placement each, where a piece pair may clear first
    const double* first;    // (E,): the reach a piece pair clears at ca, cb
    const double *ta, *tb;  // (E, KA, 4, 4), (E, KB, 4, 4)
    const int64_t *count_a, *count_b;  // (E,): the copies used, at most KA, KB
    int64_t ka, kb;
    const double *pad_a, *pad_b, *reach;
    bool settle;
    double* lowest;  // (E,)
};

// Placement e: whether the hulls of each piece's copies, less both pads, stay farther apart
// than reach. A piece pair farther apart than first[e] (when not negative) at the single
// placements ca[e], cb[e] is passed over: the caller knows it clear another way. The piece pairs whose boxes come within reach are measured by GJK, nearest boxes
// first; with settle the first within reach answers (its distance, or 0 less the pads where
// the hulls meet), else the least. -inf when a transform is not finite.
inline double copied_distance(const CopiedBatch& t, int64_t e, CopiedPieces& ca,
                              CopiedPieces& cb, CopiedPieces& sa, CopiedPieces& sb,
                              PlacedWork& w, PlacedWorkDone& done) {
    const double reach = t.reach[e];
    const int64_t na = t.count_a[e], nb = t.count_b[e];
    if (std::isnan(reach) || na < 1 || nb < 1 || na > t.ka || nb > t.kb) return -INF;
    const double* Ta = t.ta + 16 * t.ka * e;
    const double* Tb = t.tb + 16 * t.kb * e;
    const double* Sa = t.ca + 16 * e;
    const double* Sb = t.cb + 16 * e;
    if (!bound_copies(t.a, Ta, na, ca) || !bound_copies(t.b, Tb, nb, cb) ||
        !bound_copies(t.a, Sa, 1, sa) || !bound_copies(t.b, Sb, 1, sb))
        return -INF;
    box_candidates(ca.lower.data(), ca.upper.data(), t.a.m, cb.lower.data(), cb.upper.data(),
                   t.b.m, t.pad_a, t.pad_b, reach, w);
    done.boxes += t.a.m * t.b.m;
    size_t count = w.cand_i.size();
    std::vector<size_t> order(count);
    for (size_t c = 0; c < count; ++c) order[c] = c;
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t x, size_t y) { return w.cand_key[x] < w.cand_key[y]; });
    double lowest = INF;
    for (size_t c : order) {
        int64_t i = w.cand_i[c], j = w.cand_j[c];
        double pad = t.pad_a[i] + t.pad_b[j];
        if (t.first[e] >= 0.0) {  // the pair clears at the single placements: no copies
            place_copies(t.a, Sa, 1, i, sa);
            place_copies(t.b, Sb, 1, j, sb);
            Shape A{sa.points.data(), nullptr, nullptr, t.a.starts[i], t.a.starts[i + 1], false};
            Shape B{sb.points.data(), nullptr, nullptr, t.b.starts[j], t.b.starts[j + 1], false};
            Frame fr = make_frame(sa.lower.data() + 3 * i, sa.upper.data() + 3 * i,
                                  sb.lower.data() + 3 * j, sb.upper.data() + 3 * j, 0.0);
            Answer out;
            ++done.queries;
            if (gjk(A, B, fr, t.first[e] + pad, w.s, out) == 0 &&
                static_cast<int>(out.v[0]) != K.undecided && out.v[1] - pad > t.first[e])
                continue;
        }
        place_copies(t.a, Ta, na, i, ca);
        place_copies(t.b, Tb, nb, j, cb);
        Shape A{ca.points.data(), nullptr, nullptr, na * t.a.starts[i], na * t.a.starts[i + 1],
                false};
        Shape B{cb.points.data(), nullptr, nullptr, nb * t.b.starts[j], nb * t.b.starts[j + 1],
                false};
        Frame fr = make_frame(ca.lower.data() + 3 * i, ca.upper.data() + 3 * i,
                              cb.lower.data() + 3 * j, cb.upper.data() + 3 * j, 0.0);
        Answer out;
        ++done.queries;
        done.supports += na + nb;
        double d = 0.0;  // the hulls meet
        if (gjk(A, B, fr, reach + pad, w.s, out) == 0) {
            d = out.v[1];
            if (static_cast<int>(out.v[0]) == K.undecided) d = std::min(d, 0.0);
        }
        lowest = std::min(lowest, d - pad);
        if (t.settle && lowest <= reach) break;
    }
    return lowest;
}

inline PlacedWorkDone copied_distances(const CopiedBatch& t, int64_t count) {
    PlacedWork w;
    CopiedPieces ca, cb, sa, sb;
    PlacedWorkDone done;
    for (int64_t e = 0; e < count; ++e)
        t.lowest[e] = copied_distance(t, e, ca, cb, sa, sb, w, done);
    return done;
}

}  // namespace meshcheck
