// Exact triangle-triangle distance, the triangle pairs of two meshes within reach, and points
// against a whole mesh (winding numbers, distances, the inscribed ball): the verify stage.
//
// Every function takes vertices (n, 3) and faces (m, 3) in a frame the caller has re-centred
// near the region of interest, so coordinates far from the origin keep their digits.
#pragma once

#include <algorithm>
#include <numeric>
#include <vector>

#include "vec.hpp"

namespace meshcheck {

constexpr int64_t BVH_LEAF = 4;  // triangles per BVH leaf

// Triangles this flat (sine of a corner below it) have no interior worth a Voronoi test: their
// nearest points are on their edges, which the callers also measure.
constexpr double FLAT_SIN = 1e-15;

inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

struct Tri {
    V3 p[3];
};

inline Tri triangle(const double* v, const int64_t* f, int64_t k) {
    return {{row(v, f[3 * k]), row(v, f[3 * k + 1]), row(v, f[3 * k + 2])}};
}

// Closest point to p on triangle t; `flat` says the triangle was degenerate (then the point is
// on its best edge).
inline V3 closest_point_triangle(V3 p, const Tri& t, bool& flat) {
    double la, lb, lc;
    flat = closest_on_triangle(p, t.p[0], t.p[1], t.p[2], FLAT_SIN, la, lb, lc);
    return t.p[0] * la + t.p[1] * lb + t.p[2] * lc;
}

// Closest points between segments p1 q1 and p2 q2 (Ericson 5.1.9).
inline void closest_points_segments(V3 p1, V3 q1, V3 p2, V3 q2, V3& x, V3& y) {
    V3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
    double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
    const double tiny = 1e-300;
    if (a <= tiny && e <= tiny) {
        x = p1, y = p2;
        return;
    }
    double s, t;
    if (a <= tiny) {
        s = 0.0;
        t = clamp01(f / e);
    } else {
        double c = dot(d1, r);
        if (e <= tiny) {
            t = 0.0;
            s = clamp01(-c / a);
        } else {
            double b = dot(d1, d2);
            double denom = a * e - b * b;
            s = denom > 1e-14 * a * e ? clamp01((b * f - c * e) / denom) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = clamp01(-c / a);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp01((b - c) / a);
            }
        }
    }
    x = p1 + d1 * s;
    y = p2 + d2 * t;
}

// Where segment pq passes strictly through the interior of triangle abc (returns true and the
// point); false when it does not, or only grazes an edge, a vertex or the plane (those contacts
// are found by the vertex-triangle and edge-edge distances).
inline bool segment_crosses(V3 p, V3 q, V3 a, V3 b, V3 c, V3& x) {
    V3 n = cross(b - a, c - a);
    double sp = dot(n, p - a), sq = dot(n, q - a);
    if (!((sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0))) return false;
    x = p + (q - p) * (sp / (sp - sq));
    double c1 = dot(cross(b - a, x - a), n);
    double c2 = dot(cross(c - b, x - b), n);
    double c3 = dot(cross(a - c, x - c), n);
    return c1 > 0.0 && c2 > 0.0 && c3 > 0.0;
}

// Exact distance between two triangles, with witness points; `crossing` when an edge of one
// passes strictly through the interior of the other (distance 0, both points the crossing).
inline double triangle_distance(const Tri& ta, const Tri& tb, V3& pa, V3& pb, bool& crossing) {
    crossing = false;
    for (int i = 0; i < 3; ++i) {
        V3 x;
        if (segment_crosses(ta.p[i], ta.p[(i + 1) % 3], tb.p[0], tb.p[1], tb.p[2], x) ||
            segment_crosses(tb.p[i], tb.p[(i + 1) % 3], ta.p[0], ta.p[1], ta.p[2], x)) {
            pa = pb = x;
            crossing = true;
            return 0.0;
        }
    }
    double best = INF;
    pa = ta.p[0], pb = tb.p[0];
    for (int i = 0; i < 3; ++i) {
        bool flat;
        V3 q = closest_point_triangle(ta.p[i], tb, flat);
        if (!flat) {
            double dd = dist2(ta.p[i], q);
            if (dd < best) best = dd, pa = ta.p[i], pb = q;
        }
        q = closest_point_triangle(tb.p[i], ta, flat);
        if (!flat) {
            double dd = dist2(tb.p[i], q);
            if (dd < best) best = dd, pa = q, pb = tb.p[i];
        }
    }
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            V3 x, y;
            closest_points_segments(ta.p[i], ta.p[(i + 1) % 3], tb.p[j], tb.p[(j + 1) % 3], x, y);
            double dd = dist2(x, y);
            if (dd < best) best = dd, pa = x, pb = y;
        }
    }
    return std::sqrt(best);
}

// How far two crossing triangles pass through each other: the least of the four reaches of one
// triangle beyond the other's plane, on either side. Near 0 for faces resting on faces.
inline double crossing_strength(const Tri& ta, const Tri& tb) {
    double out = INF;
    for (int s = 0; s < 2; ++s) {
        const Tri& p = s == 0 ? ta : tb;
        const Tri& q = s == 0 ? tb : ta;
        V3 n = cross(q.p[1] - q.p[0], q.p[2] - q.p[0]);
        double ln = std::sqrt(dot(n, n));
        if (ln == 0.0) return 0.0;
        double h0 = dot(n, p.p[0] - q.p[0]) / ln;
        double h1 = dot(n, p.p[1] - q.p[0]) / ln;
        double h2 = dot(n, p.p[2] - q.p[0]) / ln;
        out = std::min({out, std::max({h0, h1, h2}), -std::min({h0, h1, h2})});
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Triangle pairs of two meshes within reach: a BVH over one set of boxes, queried with the other

// Axis-aligned boxes of triangles into lo, hi (m, 3).
inline void triangle_boxes(const double* v, const int64_t* f, int64_t m, double* lo, double* hi) {
    for (int64_t k = 0; k < m; ++k) {
        for (int d = 0; d < 3; ++d) {
            double x0 = v[3 * f[3 * k] + d], x1 = v[3 * f[3 * k + 1] + d];
            double x2 = v[3 * f[3 * k + 2] + d];
            lo[3 * k + d] = std::min({x0, x1, x2});
            hi[3 * k + d] = std::max({x0, x1, x2});
        }
    }
}

// Median-split BVH over boxes. A node is a leaf when child < 0 (its boxes are
// order[start:start + count]); else its children are child and child + 1.
struct Bvh {
    std::vector<double> lo, hi;  // (n, 3) node boxes
    std::vector<int64_t> child, start, count, order;
};

inline Bvh build_bvh(const double* lo, const double* hi, int64_t m) {
    Bvh t;
    int64_t cap = std::max<int64_t>(2 * m, 1);
    t.lo.assign(3 * cap, 0.0), t.hi.assign(3 * cap, 0.0);
    t.child.assign(cap, -1), t.start.assign(cap, 0), t.count.assign(cap, 0);
    t.order.resize(m);
    std::iota(t.order.begin(), t.order.end(), 0);
    std::vector<double> cent(3 * m);
    for (int64_t k = 0; k < 3 * m; ++k) cent[k] = 0.5 * (lo[k] + hi[k]);
    struct Range {
        int64_t node, s, e;
    };
    std::vector<Range> stack{{0, 0, m}};
    int64_t n_nodes = 1;
    while (!stack.empty()) {
        auto [node, s, e] = stack.back();
        stack.pop_back();
        double clo[3] = {INF, INF, INF}, chi[3] = {-INF, -INF, -INF};
        double* nlo = &t.lo[3 * node];
        double* nhi = &t.hi[3 * node];
        for (int d = 0; d < 3; ++d) nlo[d] = INF, nhi[d] = -INF;
        for (int64_t i = s; i < e; ++i) {
            int64_t k = t.order[i];
            for (int d = 0; d < 3; ++d) {
                nlo[d] = std::min(nlo[d], lo[3 * k + d]);
                nhi[d] = std::max(nhi[d], hi[3 * k + d]);
                clo[d] = std::min(clo[d], cent[3 * k + d]);
                chi[d] = std::max(chi[d], cent[3 * k + d]);
            }
        }
        if (e - s <= BVH_LEAF) {
            t.start[node] = s;
            t.count[node] = e - s;
            continue;
        }
        int axis = 0;  // the first axis of largest centroid spread
        for (int d = 1; d < 3; ++d)
            if (chi[d] - clo[d] > chi[axis] - clo[axis]) axis = d;
        std::stable_sort(t.order.begin() + s, t.order.begin() + e, [&](int64_t i, int64_t j) {
            return cent[3 * i + axis] < cent[3 * j + axis];
        });
        int64_t mid = (s + e) / 2;
        t.child[node] = n_nodes;
        stack.push_back({n_nodes, s, mid});
        stack.push_back({n_nodes + 1, mid, e});
        n_nodes += 2;
    }
    t.lo.resize(3 * n_nodes), t.hi.resize(3 * n_nodes);
    t.child.resize(n_nodes), t.start.resize(n_nodes), t.count.resize(n_nodes);
    return t;
}

inline bool boxes_near(const double* alo, const double* ahi, const double* blo,
                       const double* bhi, double reach) {
    for (int d = 0; d < 3; ++d)
        if (alo[d] > bhi[d] + reach || blo[d] > ahi[d] + reach) return false;
    return true;
}

// Pairs (i, j) of boxes of two sets whose gap is at most `reach` along every axis, appended to
// `out` as i, j, i, j, ...
inline void box_pairs(const double* alo, const double* ahi, int64_t ma, const double* blo,
                      const double* bhi, int64_t mb, double reach, std::vector<int64_t>& out) {
    if (ma == 0 || mb == 0) return;
    Bvh t = build_bvh(blo, bhi, mb);
    std::vector<int64_t> stack;
    for (int64_t i = 0; i < ma; ++i) {
        const double* lo_i = alo + 3 * i;
        const double* hi_i = ahi + 3 * i;
        stack.assign(1, 0);
        while (!stack.empty()) {
            int64_t node = stack.back();
            stack.pop_back();
            if (!boxes_near(lo_i, hi_i, &t.lo[3 * node], &t.hi[3 * node], reach)) continue;
            if (t.child[node] < 0) {
                for (int64_t r = t.start[node]; r < t.start[node] + t.count[node]; ++r) {
                    int64_t j = t.order[r];
                    if (boxes_near(lo_i, hi_i, blo + 3 * j, bhi + 3 * j, reach)) {
                        out.push_back(i);
                        out.push_back(j);
                    }
                }
            } else {
                stack.push_back(t.child[node]);
                stack.push_back(t.child[node] + 1);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Points against a whole mesh

// Generalized winding number of p (1 inside a closed outward mesh, 0 outside): Van Oosterom
// and Strackee's solid angle of each triangle, summed over 4 pi.
inline double winding_number(V3 p, const double* v, const int64_t* f, int64_t m) {
    double total = 0.0;
    for (int64_t k = 0; k < m; ++k) {
        Tri t = triangle(v, f, k);
        V3 a = t.p[0] - p, b = t.p[1] - p, c = t.p[2] - p;
        double la = std::sqrt(dot(a, a)), lb = std::sqrt(dot(b, b)), lc = std::sqrt(dot(c, c));
        double num = dot(a, cross(b, c));
        double den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
        total += 2.0 * std::atan2(num, den);
    }
    return total / (4.0 * M_PI);
}

// Closest point to p on triangle t, degenerate triangles included.
inline V3 closest_on_tri(V3 p, const Tri& t) {
    bool flat;
    return closest_point_triangle(p, t, flat);
}

inline double point_mesh_distance(V3 p, const double* v, const int64_t* f, int64_t m) {
    double best = INF;
    for (int64_t k = 0; k < m; ++k) {
        best = std::min(best, dist2(p, closest_on_tri(p, triangle(v, f, k))));
    }
    return std::sqrt(best);
}

// Moller-Trumbore: the ray o + t d meets triangle t at `tt` (true), or misses it (false).
inline bool ray_triangle(V3 o, V3 d, const Tri& t, double& tt) {
    V3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0];
    V3 h = cross(d, e2);
    double det = dot(e1, h);
    if (det == 0.0) return false;
    double inv = 1.0 / det;
    V3 s = o - t.p[0];
    double u = dot(s, h) * inv;
    if (u < 0.0 || u > 1.0) return false;
    V3 q = cross(s, e1);
    double w = dot(d, q) * inv;
    if (w < 0.0 || u + w > 1.0) return false;
    tt = dot(e2, q) * inv;
    return true;
}

// Smallest t > beyond where the ray o + t d meets a triangle other than `skip`
// (Moller-Trumbore; INF when none).
inline double ray_first_hit(V3 o, V3 d, const double* v, const int64_t* f, int64_t m,
                            int64_t skip, double beyond = 0.0) {
    double best = INF;
    for (int64_t k = 0; k < m; ++k) {
        double tt;
        if (k != skip && ray_triangle(o, d, triangle(v, f, k), tt) && beyond < tt && tt < best)
            best = tt;
    }
    return best;
}

// ---------------------------------------------------------------------------------------------
// The same point and ray queries through a BVH over the triangles, for many queries of one mesh.
// Each answer is the brute-force one, bit for bit: a minimum does not depend on the order it is
// taken in, and a node is skipped only when its box, grown by a margin far above rounding (so a
// triangle's computed closest point or hit point cannot fall outside it), proves that none of
// its triangles can beat the best so far.

struct MeshBvh {
    const double* v;
    const int64_t* f;
    int64_t m;
    Bvh t;
    double pad;
    MeshBvh(const double* v_, const int64_t* f_, int64_t m_) : v(v_), f(f_), m(m_) {
        std::vector<double> lo(3 * std::max<int64_t>(m, 1)), hi(3 * std::max<int64_t>(m, 1));
        triangle_boxes(v, f, m, lo.data(), hi.data());
        t = build_bvh(lo.data(), hi.data(), m);
        double size = 0.0;
        for (size_t k = 0; k < 3 && m > 0; ++k)
            size = std::max({size, t.hi[k] - t.lo[k], std::fabs(t.hi[k]), std::fabs(t.lo[k])});
        pad = 1e-9 * size;
        for (auto& x : t.lo) x -= pad;
        for (auto& x : t.hi) x += pad;
    }
    bool leaf(int64_t node) const { return t.child[node] < 0; }
};

inline double box_dist2(V3 p, const double* lo, const double* hi) {
    double c[3] = {p.x, p.y, p.z}, s = 0.0;
    for (int d = 0; d < 3; ++d) {
        double e = std::max({lo[d] - c[d], 0.0, c[d] - hi[d]});
        s += e * e;
    }
    return s;
}

// The distance from p to the mesh when it exceeds r, else -1 (as soon as one triangle is within
// r, trying triangle `hint` first and leaving there the one found); r < 0: the plain distance.
// The value returned is point_mesh_distance's, bit for bit: sqrt is monotonic, so sqrt(min d2) >
// r exactly when every sqrt(d2) > r, and a minimum does not depend on the order it is taken in.
inline double bvh_distance_beyond(const MeshBvh& b, V3 p, double r, int64_t& hint) {
    if (r >= 0.0 && hint >= 0 && hint < b.m &&
        std::sqrt(dist2(p, closest_on_tri(p, triangle(b.v, b.f, hint)))) <= r)
        return -1.0;
    double best = INF;
    std::vector<int64_t> stack{0};
    while (!stack.empty() && b.m > 0) {
        int64_t node = stack.back();
        stack.pop_back();
        if (box_dist2(p, &b.t.lo[3 * node], &b.t.hi[3 * node]) > best) continue;
        if (b.leaf(node)) {
            for (int64_t i = b.t.start[node]; i < b.t.start[node] + b.t.count[node]; ++i) {
                int64_t k = b.t.order[i];
                double d2 = dist2(p, closest_on_tri(p, triangle(b.v, b.f, k)));
                if (r >= 0.0 && std::sqrt(d2) <= r) {
                    hint = k;
                    return -1.0;
                }
                best = std::min(best, d2);
            }
            continue;
        }
        int64_t c = b.t.child[node];
        bool near_first = box_dist2(p, &b.t.lo[3 * c], &b.t.hi[3 * c]) <=
                          box_dist2(p, &b.t.lo[3 * c + 3], &b.t.hi[3 * c + 3]);
        stack.push_back(near_first ? c + 1 : c);
        stack.push_back(near_first ? c : c + 1);
    }
    return std::sqrt(best);
}

// Entry and exit of the ray o + t d in a box (slab test): false when it misses.
inline bool ray_box(V3 o, V3 d, const double* lo, const double* hi, double& enter, double& leave) {
    double oc[3] = {o.x, o.y, o.z}, dc[3] = {d.x, d.y, d.z};
    enter = -INF, leave = INF;
    for (int k = 0; k < 3; ++k) {
        if (dc[k] == 0.0) {
            if (oc[k] < lo[k] || oc[k] > hi[k]) return false;
            continue;
        }
        double a = (lo[k] - oc[k]) / dc[k], c = (hi[k] - oc[k]) / dc[k];
        enter = std::max(enter, std::min(a, c));
        leave = std::min(leave, std::max(a, c));
    }
    return enter <= leave;
}

// ray_first_hit through the BVH.
inline double bvh_ray_first_hit(const MeshBvh& b, V3 o, V3 d, int64_t skip, double beyond) {
    double best = INF;
    const double pad = b.pad / std::sqrt(dot(d, d));  // the margin along the ray, in t
    std::vector<int64_t> stack{0};
    while (!stack.empty() && b.m > 0) {
        int64_t node = stack.back();
        stack.pop_back();
        double enter, leave;
        if (!ray_box(o, d, &b.t.lo[3 * node], &b.t.hi[3 * node], enter, leave)) continue;
        if (leave < beyond - pad || enter > best + pad) continue;
        if (!b.leaf(node)) {
            stack.push_back(b.t.child[node] + 1);
            stack.push_back(b.t.child[node]);
            continue;
        }
        for (int64_t i = b.t.start[node]; i < b.t.start[node] + b.t.count[node]; ++i) {
            int64_t k = b.t.order[i];
            double tt;
            if (k != skip && ray_triangle(o, d, triangle(b.v, b.f, k), tt) && beyond < tt &&
                tt < best)
                best = tt;
        }
    }
    return best;
}

// Largest ball inside a closed, outward-wound mesh: returns its radius, centre in x.
//
// Seeds: from the centroid of (up to max_seeds, evenly strided) faces, a ray along the inward
// normal to the first surface it meets; its midpoint is inside the solid, on the medial surface
// of any slab or shell. The best seeds are refined by a compass search over 26 directions whose
// step never exceeds the current radius, so every accepted point stays inside the solid.
inline double inscribed_ball(const double* v, const int64_t* f, int64_t m, int64_t max_seeds,
                             V3& best_x) {
    best_x = {0.0, 0.0, 0.0};
    if (m == 0) return 0.0;
    int64_t stride = std::max<int64_t>(1, m / max_seeds);
    int64_t n_seeds = (m + stride - 1) / stride;
    std::vector<V3> centres(n_seeds, V3{0.0, 0.0, 0.0});
    std::vector<double> radii(n_seeds, 0.0);
    const MeshBvh bvh(v, f, m);
    for (int64_t s = 0; s < n_seeds; ++s) {
        int64_t k = s * stride;
        Tri t = triangle(v, f, k);
        V3 n = cross(t.p[1] - t.p[0], t.p[2] - t.p[0]);
        double ln = std::sqrt(dot(n, n));
        if (ln == 0.0) continue;
        V3 inward = n * (-1.0 / ln);
        V3 o = (t.p[0] + (t.p[1] + t.p[2])) * (1.0 / 3.0);
        double hit = bvh_ray_first_hit(bvh, o, inward, k, 0.0);
        if (!std::isfinite(hit)) continue;
        centres[s] = o + inward * (0.5 * hit);
        int64_t no_hint = -1;
        radii[s] = bvh_distance_beyond(bvh, centres[s], -1.0, no_hint);
    }
    V3 dirs[26];
    int nd = 0;
    for (int i = -1; i <= 1; ++i)
        for (int j = -1; j <= 1; ++j)
            for (int k = -1; k <= 1; ++k) {
                if (i == 0 && j == 0 && k == 0) continue;
                double ln = std::sqrt(double(i * i + j * j + k * k));
                dirs[nd++] = {i / ln, j / ln, k / ln};
            }
    double best_r = 0.0;
    std::vector<int64_t> order(n_seeds);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int64_t i, int64_t j) { return radii[i] > radii[j]; });
    for (int64_t rank = 0; rank < std::min<int64_t>(8, n_seeds); ++rank) {
        int64_t s = order[rank];
        double r = radii[s];
        if (r <= 0.0) break;
        V3 x = centres[s];
        double step = 0.5 * r;
        int64_t hint = -1;  // a triangle near the last point tried: most steps fail on it
        for (int it = 0; it < 200; ++it) {
            if (step <= 1e-6 * r) break;
            bool moved = false;
            for (const V3& d : dirs) {
                V3 y = x + d * step;
                double ry = bvh_distance_beyond(bvh, y, r, hint);
                if (ry > r) {
                    x = y, r = ry, moved = true;
                    break;
                }
            }
            step = moved ? std::min(2.0 * step, 0.9 * r) : 0.5 * step;
        }
        if (r > best_r) best_r = r, best_x = x;
    }
    return best_r;
}

}  // namespace meshcheck
