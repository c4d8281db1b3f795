// The GJK simplex: up to four Minkowski points with their sources, and one small function per
// simplex size (do_simplex2/3/4, as libccd) that keeps its feature nearest the origin.
#pragma once

#include "support.hpp"

namespace meshcheck {

struct Simplex {
    CsoPoint p[4];
    double lam[4];  // barycentric weights of the simplex point nearest the origin
    int k;          // number of points
};

// Drop points of zero weight, keeping order; return the new size.
inline int compact(Simplex& s, int k) {
    int n = 0;
    for (int r = 0; r < k; ++r) {
        if (s.lam[r] > 0.0) {
            if (n != r) {
                s.p[n] = s.p[r];
                s.lam[n] = s.lam[r];
            }
            ++n;
        }
    }
    return n;
}

constexpr V3 ORIGIN{0.0, 0.0, 0.0};

// Segment: keep the vertex or the segment nearest the origin. Returns the new size.
inline int do_simplex2(Simplex& s) {
    closest_on_segment(ORIGIN, s.p[0].w, s.p[1].w, s.lam[0], s.lam[1]);
    return compact(s, 2);
}

// Triangle: keep the vertex, edge or face nearest the origin. Returns the new size.
inline int do_simplex3(Simplex& s) {
    closest_on_triangle(ORIGIN, s.p[0].w, s.p[1].w, s.p[2].w, K.degenerate_sin, s.lam[0],
                        s.lam[1], s.lam[2]);
    return compact(s, 3);
}

// Tetrahedron: detect that it holds the origin (returns 4 and sets encloses), else keep its
// feature nearest the origin. A tetrahedron whose volume is below DEGENERATE_SIN times the
// product of its edges is flat: orientation tests on it are noise, so its nearest point is found
// over all four faces and it never claims to enclose the origin.
inline int do_simplex4(Simplex& s, bool& encloses) {
    const V3 W[4] = {s.p[0].w, s.p[1].w, s.p[2].w, s.p[3].w};
    V3 e1 = W[1] - W[0], e2 = W[2] - W[0], e3 = W[3] - W[0];
    double det = e1.x * (e2.y * e3.z - e2.z * e3.y) + e1.y * (e2.z * e3.x - e2.x * e3.z) +
                 e1.z * (e2.x * e3.y - e2.y * e3.x);
    double scale = std::sqrt(dot(e1, e1) * dot(e2, e2) * dot(e3, e3));
    bool flat = std::fabs(det) <= K.degenerate_sin * scale;
    static constexpr int FACES[4][4] = {{0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 3, 1}, {1, 2, 3, 0}};
    double best = INF;
    int bi = 0, bj = 1, bm = 2;
    double wi = 1.0, wj = 0.0, wm = 0.0;
    encloses = true;
    for (const auto& face : FACES) {
        int i = face[0], j = face[1], m = face[2], o = face[3];  // face (i, j, m) opposite o
        if (!flat) {
            V3 ab = W[j] - W[i], ac = W[m] - W[i];
            V3 n = cross(ab, ac);
            double s_origin = -(n.x * W[i].x + n.y * W[i].y + n.z * W[i].z);
            V3 io = W[o] - W[i];
            double s_opp = n.x * io.x + n.y * io.y + n.z * io.z;
            if (s_origin * s_opp >= 0.0) continue;  // the origin is on the tetrahedron's side
        }
        encloses = false;
        double li, lj, lm;
        closest_on_triangle(ORIGIN, W[i], W[j], W[m], K.degenerate_sin, li, lj, lm);
        V3 p = W[i] * li + W[j] * lj + W[m] * lm;
        double d = dot(p, p);
        if (d < best) best = d, bi = i, bj = j, bm = m, wi = li, wj = lj, wm = lm;
    }
    if (encloses) return 4;
    s.lam[0] = s.lam[1] = s.lam[2] = s.lam[3] = 0.0;
    s.lam[bi] = wi, s.lam[bj] = wj, s.lam[bm] = wm;
    return compact(s, 4);
}

// The simplex point v nearest the origin.
//
// For a triangle it is the origin's projection on the plane, n (n . a) / |n|^2 with the normal
// n from a cross product of edges (as libccd's doSimplex3 takes the normal as the new
// direction): when the shapes nearly touch, v is tiny next to the simplex points and
// sum(lam * W) would give its direction only to eps |W| / |v| (1e-6 at a 1e-10 gap), while the
// normal keeps full precision, and with it the lower bound w . v / |v|.
//
// For a segment e the same holds for the component of v along e: it is projected out once
// more, so v is square to e to eps |v| and both ends of a long thin Minkowski difference give
// the same, accurate bound (nearly collinear segments 1e-10 apart).
inline V3 nearest_point(const Simplex& s, int k) {
    if (k == 3) {
        V3 ab = s.p[1].w - s.p[0].w, ac = s.p[2].w - s.p[0].w;
        V3 n = cross(ab, ac);
        double nn = dot(n, n);
        if (nn > 0.0) {
            double t = dot(n, s.p[0].w) / nn;
            return n * t;
        }
    }
    V3 v{0.0, 0.0, 0.0};
    for (int r = 0; r < k; ++r) v = v + s.p[r].w * s.lam[r];
    if (k == 2) {
        V3 e = s.p[1].w - s.p[0].w;
        double ee = dot(e, e);
        if (ee > 0.0) {
            double t = dot(v, e) / ee;
            v = v - e * t;
        }
    }
    return v;
}

// Witness points of the simplex point nearest the origin: (sum lam a, sum lam b).
inline void simplex_witnesses(const Simplex& s, int k, V3& a, V3& b) {
    a = b = ORIGIN;
    for (int r = 0; r < k; ++r) {
        a = a + s.p[r].a * s.lam[r];
        b = b + s.p[r].b * s.lam[r];
    }
}

}  // namespace meshcheck
