// Mesh connectivity for the load stage: equal rows of integer keys (vertex merging), degenerate
// triangles, whether a triangle soup is closed and consistently oriented, and its shells.
//
// Every answer is a function of the input arrays alone (first-appearance order, never the order
// of a hash table), so the same bytes give the same mesh on every run and platform.
#pragma once

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace meshcheck {

// Group equal rows of keys (n, cols) by sorting: see group_rows.
inline int64_t group_rows_sorted(const int64_t* keys, int64_t n, int64_t cols, int64_t* inverse,
                                 std::vector<int64_t>& first) {
    first.clear();
    std::vector<int64_t> order(static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i) order[i] = i;
    auto same = [keys, cols](int64_t a, int64_t b) {
        const int64_t *x = keys + cols * a, *y = keys + cols * b;
        for (int64_t d = 0; d < cols; ++d) {
            if (x[d] != y[d]) return false;
        }
        return true;
    };
    std::sort(order.begin(), order.end(), [keys, cols](int64_t a, int64_t b) {
        const int64_t *x = keys + cols * a, *y = keys + cols * b;
        for (int64_t d = 0; d < cols; ++d) {
            if (x[d] != y[d]) return x[d] < y[d];
        }
        return a < b;
    });
    // inverse[i] first holds the first row equal to row i (the head of its run in the order).
    int64_t head = n > 0 ? order[0] : 0;
    for (int64_t r = 0; r < n; ++r) {
        int64_t i = order[r];
        if (!same(i, head)) head = i;
        inverse[i] = head;
    }
    // Number the groups by their first row: row i is first of its group when it is its own head.
    std::vector<int64_t> group(static_cast<size_t>(n), -1);
    for (int64_t i = 0; i < n; ++i) {
        if (inverse[i] == i) {
            group[i] = static_cast<int64_t>(first.size());
            first.push_back(i);
        }
        inverse[i] = group[inverse[i]];  // its head comes no later than i, so it is numbered
    }
    return static_cast<int64_t>(first.size());
}

// Group equal rows of keys (n, cols): inverse[i] is the group of row i, groups numbered in the
// order of their first row; first receives each group's first row. Returns the number of groups.
// A hash table answers in linear time; keys crafted to collide in it (probing beyond a fixed
// budget) switch to sorting, O(n log n) whatever the keys. Both give the same answer.
inline int64_t group_rows(const int64_t* keys, int64_t n, int64_t cols, int64_t* inverse,
                          std::vector<int64_t>& first) {
    first.clear();
    if (n <= 0) return 0;
    uint64_t capacity = 16;
    while (capacity < 2 * static_cast<uint64_t>(n)) capacity <<= 1;
    const uint64_t mask = capacity - 1;
    std::vector<int64_t> slot(capacity, -1);  // group id, or -1 when empty
    int64_t probes = 0;
    const int64_t budget = 16 * n + 1024;
    for (int64_t i = 0; i < n; ++i) {
        const int64_t* k = keys + cols * i;
        uint64_t h = 0x9e3779b97f4a7c15ULL;
        for (int64_t d = 0; d < cols; ++d) {  // splitmix64 finaliser over the row
            h ^= static_cast<uint64_t>(k[d]);
            h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ULL;
            h = (h ^ (h >> 27)) * 0x94d049bb133111ebULL;
            h ^= h >> 31;
        }
        for (uint64_t s = h & mask;; s = (s + 1) & mask) {
            int64_t g = slot[s];
            if (g < 0) {
                slot[s] = static_cast<int64_t>(first.size());
                inverse[i] = slot[s];
                first.push_back(i);
                break;
            }
            const int64_t* o = keys + cols * first[g];
            bool equal = true;
            for (int64_t d = 0; d < cols && equal; ++d) equal = o[d] == k[d];
            if (equal) {
                inverse[i] = g;
                break;
            }
            if (++probes > budget) return group_rows_sorted(keys, n, cols, inverse, first);
        }
    }
    return static_cast<int64_t>(first.size());
}

// Degenerate triangles: repeated[k] when triangle k names a vertex twice; flat[k] when it is
// repeated or its cross product (b - a) x (c - a) is exactly zero, component by component as
// plain IEEE double operations (a NaN component is not zero).
inline void degenerate_triangles(const double* v, const int64_t* f, int64_t m, bool* repeated,
                                 bool* flat) {
    for (int64_t k = 0; k < m; ++k) {
        const int64_t a = f[3 * k], b = f[3 * k + 1], c = f[3 * k + 2];
        repeated[k] = a == b || b == c || a == c;
        const double* p = v + 3 * a;
        const double* q = v + 3 * b;
        const double* r = v + 3 * c;
        const double u0 = q[0] - p[0], u1 = q[1] - p[1], u2 = q[2] - p[2];
        const double w0 = r[0] - p[0], w1 = r[1] - p[1], w2 = r[2] - p[2];
        const double x = u1 * w2 - u2 * w1, y = u2 * w0 - u0 * w2, z = u0 * w1 - u1 * w0;
        flat[k] = repeated[k] || !(x != 0.0 || y != 0.0 || z != 0.0);
    }
}

// is_closed for faces whose indices span a huge range: sort every directed edge.
inline bool is_closed_sorted(const int64_t* f, int64_t m) {
    std::vector<std::pair<int64_t, int64_t>> edges(3 * static_cast<size_t>(m));
    for (int64_t k = 0; k < m; ++k) {
        for (int e = 0; e < 3; ++e) edges[3 * k + e] = {f[3 * k + e], f[3 * k + (e + 1) % 3]};
    }
    std::sort(edges.begin(), edges.end());
    for (size_t i = 1; i < edges.size(); ++i) {
        if (edges[i] == edges[i - 1]) return false;  // used twice the same way
    }
    for (const auto& [a, b] : edges) {
        if (!std::binary_search(edges.begin(), edges.end(), std::make_pair(b, a))) return false;
    }
    return true;
}

// True when every directed edge (a, b) of the triangles occurs exactly once and its reverse
// (b, a) occurs too: every edge joins exactly two triangles that agree on their orientation.
// An edge from a vertex to itself (a triangle with a repeated vertex) makes the mesh not closed.
inline bool is_closed(const int64_t* f, int64_t m) {
    if (m <= 0) return false;
    const int64_t e = 3 * m;
    int64_t lo = f[0], hi = f[0];
    for (int64_t i = 0; i < e; ++i) {
        lo = std::min(lo, f[i]), hi = std::max(hi, f[i]);
        if (f[i] == f[i - i % 3 + (i % 3 + 1) % 3]) return false;
    }
    if (lo < 0 || hi - lo > 4 * e) return is_closed_sorted(f, m);  // sparse: no table per vertex
    // The heads of each tail's edges, grouped by tail (a counting sort), each group sorted.
    const int64_t n = hi - lo + 1;
    std::vector<int64_t> start(static_cast<size_t>(n) + 1, 0), head(static_cast<size_t>(e));
    for (int64_t i = 0; i < e; ++i) ++start[f[i] - lo + 1];
    for (int64_t v = 0; v < n; ++v) start[v + 1] += start[v];
    std::vector<int64_t> fill(start.begin(), start.end() - 1);
    for (int64_t i = 0; i < e; ++i) head[fill[f[i] - lo]++] = f[i - i % 3 + (i % 3 + 1) % 3];
    for (int64_t v = 0; v < n; ++v) {
        auto b = head.begin() + start[v], end = head.begin() + start[v + 1];
        std::sort(b, end);
        if (std::adjacent_find(b, end) != end) return false;  // an edge used twice the same way
    }
    for (int64_t v = 0; v < n; ++v) {
        for (int64_t j = start[v]; j < start[v + 1]; ++j) {
            const int64_t w = head[j] - lo;  // edge v -> w needs w -> v
            if (!std::binary_search(head.begin() + start[w], head.begin() + start[w + 1], v + lo))
                return false;
        }
    }
    return true;
}

// Connected shells of a triangle mesh: triangles sharing a vertex are in one shell. label[k] is
// the shell of triangle k, shells numbered by their first triangle; returns the number of shells.
// Face indices must lie in [0, n_vertices).
inline int64_t shell_labels(const int64_t* f, int64_t m, int64_t n_vertices, int64_t* label) {
    std::vector<int64_t> parent(static_cast<size_t>(std::max<int64_t>(n_vertices, 0)));
    for (int64_t i = 0; i < n_vertices; ++i) parent[i] = i;
    auto root = [&](int64_t x) {
        while (parent[x] != x) {
            parent[x] = parent[parent[x]];  // path halving
            x = parent[x];
        }
        return x;
    };
    auto join = [&](int64_t a, int64_t b) {
        a = root(a), b = root(b);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
    };
    for (int64_t k = 0; k < m; ++k) {
        join(f[3 * k], f[3 * k + 1]);
        join(f[3 * k + 1], f[3 * k + 2]);
    }
    std::vector<int64_t> shell(parent.size(), -1);
    int64_t count = 0;
    for (int64_t k = 0; k < m; ++k) {
        int64_t r = root(f[3 * k]);
        if (shell[r] < 0) shell[r] = count++;
        label[k] = shell[r];
    }
    return count;
}

}  // namespace meshcheck
