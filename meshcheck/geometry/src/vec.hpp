// 3-vectors, the tolerances read from constants.py, and the answer record shared by the kernels.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

namespace meshcheck {

constexpr double INF = std::numeric_limits<double>::infinity();

struct V3 {
    double x, y, z;
};

inline V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(V3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(V3 a, V3 b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline V3 row(const double* p, int64_t i) { return {p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

// The tolerances of meshcheck/geometry/constants.py (the one place they are defined and
// explained); the extension reads them from that module when it is imported.
struct Constants {
    double touch_rel, coord_rel, gjk_rel_gap, zero_rel, degenerate_sin, epa_rel_gap;
    int64_t gjk_max_iter, epa_max_iter;
    int separated, touching, penetrating, undecided;
};
inline Constants K;

// One answer: [status, distance, point_a(3), point_b(3), normal(3)], world coordinates.
struct Answer {
    double v[11];
};

// Store one answer, moving the witness points back to world coordinates. A normal that cannot
// be normalised (zero length) is replaced by +x so nothing is ever NaN.
inline void write_answer(Answer& out, int status, double distance, V3 a, V3 b, V3 n,
                         const double* centre) {
    double nn = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (nn > 0.0 && std::isfinite(nn)) {
        n = {n.x / nn, n.y / nn, n.z / nn};
    } else {
        n = {1.0, 0.0, 0.0};
    }
    if (!std::isfinite(distance)) distance = 0.0;
    out.v[0] = status;
    out.v[1] = distance + 0.0;  // + 0.0 turns -0.0 into 0.0
    out.v[2] = a.x + centre[0];
    out.v[3] = a.y + centre[1];
    out.v[4] = a.z + centre[2];
    out.v[5] = b.x + centre[0];
    out.v[6] = b.y + centre[1];
    out.v[7] = b.z + centre[2];
    out.v[8] = n.x + 0.0;
    out.v[9] = n.y + 0.0;
    out.v[10] = n.z + 0.0;
}

// ---------------------------------------------------------------------------------------------
// Closest points on a segment and on a triangle: the one routine of each, used by the GJK
// simplex (nearest the origin) and by the triangle kernels (nearest a point).

// Barycentric weights (la, lb) of the point of segment ab nearest p.
inline void closest_on_segment(V3 p, V3 a, V3 b, double& la, double& lb) {
    V3 e = b - a;
    double den = dot(e, e);
    if (den <= 0.0) {
        la = 0.0, lb = 1.0;
        return;
    }
    double t = dot(p - a, e) / den;
    if (t <= 0.0) {
        la = 1.0, lb = 0.0;
    } else if (t >= 1.0) {
        la = 0.0, lb = 1.0;
    } else {
        la = 1.0 - t, lb = t;
    }
}

inline double dist2(V3 p, V3 q) {
    V3 d = q - p;
    return dot(d, d);
}

// Barycentric weights (la, lb, lc) of the point of triangle abc nearest p: the Voronoi-region
// tests of Ericson (Real-Time Collision Detection, 5.1.5). A needle or zero-area triangle (the
// sine of its corner at a below min_sin) is answered by its best edge, and the return value
// says so (true: degenerate).
inline bool closest_on_triangle(V3 p, V3 a, V3 b, V3 c, double min_sin, double& la, double& lb,
                                double& lc) {
    V3 ab = b - a, ac = c - a;
    V3 n = cross(ab, ac);
    double ab2 = dot(ab, ab), ac2 = dot(ac, ac);
    double bc2 = dist2(b, c);
    double n2 = dot(n, n);
    if (n2 <= min_sin * min_sin * ab2 * ac2 || bc2 <= 0.0) {
        double best = INF, s, t;
        la = lb = lc = 0.0;
        closest_on_segment(p, a, b, s, t);
        double d = dist2(a * s + b * t, p);
        if (d < best) best = d, la = s, lb = t, lc = 0.0;
        closest_on_segment(p, a, c, s, t);
        d = dist2(a * s + c * t, p);
        if (d < best) best = d, la = s, lb = 0.0, lc = t;
        closest_on_segment(p, b, c, s, t);
        d = dist2(b * s + c * t, p);
        if (d < best) best = d, la = 0.0, lb = s, lc = t;
        return true;
    }
    V3 ap = p - a;
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        la = 1.0, lb = 0.0, lc = 0.0;
        return false;
    }
    V3 bp = p - b;
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        la = 0.0, lb = 1.0, lc = 0.0;
        return false;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double t = d1 / (d1 - d3);
        la = 1.0 - t, lb = t, lc = 0.0;
        return false;
    }
    V3 cp = p - c;
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        la = 0.0, lb = 0.0, lc = 1.0;
        return false;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double t = d2 / (d2 - d6);
        la = 1.0 - t, lb = 0.0, lc = t;
        return false;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        la = 0.0, lb = 1.0 - t, lc = t;
        return false;
    }
    double denom = va + vb + vc;
    double v = vb / denom, w = vc / denom;
    la = 1.0 - v - w, lb = v, lc = w;
    return false;
}

}  // namespace meshcheck
