// meshcheck.geometry._kernels: the compiled geometry kernels, built at `pip install`.
//
// The algorithms live in the headers (support, simplex, gjk, epa, triangles); this file only
// turns Python arguments into arrays, checks every index it will follow (the inputs are
// hostile), releases the GIL around the work and builds the results. The Python modules
// gjk.py and triangles.py hold the documented public functions; call those, not these.
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <atomic>
#include <exception>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>

#include "epa.hpp"
#include "lp.hpp"
#include "placed.hpp"
#include "topology.hpp"
#include "triangles.hpp"

using namespace meshcheck;

namespace {

// The GIL released for the life of a scope, and taken back however the scope ends: a C++
// exception (std::bad_alloc from a vector) unwinding through the work must find the GIL held
// again when `guarded` turns it into a Python exception.
struct NoGil {
    PyThreadState* saved;
    NoGil() : saved(PyEval_SaveThread()) {}
    ~NoGil() { PyEval_RestoreThread(saved); }
    NoGil(const NoGil&) = delete;
    NoGil& operator=(const NoGil&) = delete;
};

// A kernel entry point whose C++ exceptions become Python ones instead of aborting the
// interpreter: std::bad_alloc is MemoryError (the caller says what ran out), anything else a
// RuntimeError with its message.
template <PyObject* (*F)(PyObject*, PyObject*)>
PyObject* guarded(PyObject* self, PyObject* args) {
    try {
        return F(self, args);
    } catch (const std::bad_alloc&) {
        return PyErr_NoMemory();
    } catch (const std::exception& e) {
        PyErr_SetString(PyExc_RuntimeError, e.what());
        return nullptr;
    }
}

// An owned reference to a C-contiguous, aligned array of one dtype.
struct Array {
    PyArrayObject* a = nullptr;
    Array() = default;
    Array(const Array&) = delete;
    Array& operator=(const Array&) = delete;
    ~Array() { Py_XDECREF(reinterpret_cast<PyObject*>(a)); }
    npy_intp len(int axis = 0) const { return PyArray_DIM(a, axis); }
    double* f8() const { return static_cast<double*>(PyArray_DATA(a)); }
    int64_t* i8() const { return static_cast<int64_t*>(PyArray_DATA(a)); }
    PyObject* release() {
        PyObject* o = reinterpret_cast<PyObject*>(a);
        a = nullptr;
        return o;
    }
};

// Read `obj` as an array of `type` with `ndim` dimensions (and `cols` columns when ndim == 2),
// converting when needed. Outputs (`out`) must already be exactly that, and writeable.
bool as_array(PyObject* obj, int type, int ndim, npy_intp cols, const char* name, Array& arr,
              bool out = false) {
    int flags = NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED;
    if (out) {
        if (!PyArray_Check(obj) || PyArray_TYPE(reinterpret_cast<PyArrayObject*>(obj)) != type ||
            !PyArray_ISCARRAY(reinterpret_cast<PyArrayObject*>(obj))) {
            PyErr_Format(PyExc_TypeError, "%s: expected a writeable C-contiguous array", name);
            return false;
        }
        flags |= NPY_ARRAY_WRITEABLE;
    }
    arr.a = reinterpret_cast<PyArrayObject*>(PyArray_FROMANY(obj, type, ndim, ndim, flags));
    if (arr.a == nullptr) return false;
    if (ndim == 2 && PyArray_DIM(arr.a, 1) != cols) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd columns", name, (Py_ssize_t)cols);
        return false;
    }
    return true;
}

PyObject* new_array(int ndim, npy_intp rows, int type, Array& arr) {
    npy_intp dims[2] = {rows, 3};
    arr.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(ndim, dims, type));
    return reinterpret_cast<PyObject*>(arr.a);
}

// Every value of idx[0:n] in [0, bound).
bool indices_in(const int64_t* idx, npy_intp n, int64_t bound, const char* name) {
    for (npy_intp i = 0; i < n; ++i) {
        if (idx[i] < 0 || idx[i] >= bound) {
            PyErr_Format(PyExc_ValueError, "%s: index out of range", name);
            return false;
        }
    }
    return true;
}

bool faces_of(PyObject* fo, npy_intp n_vertices, const char* name, Array& f) {
    return as_array(fo, NPY_INT64, 2, 3, name, f) &&
           indices_in(f.i8(), 3 * f.len(), n_vertices, name);
}

// Fill the AABB lo, hi of n points; false if a coordinate is not finite.
bool bounds(const double* pts, npy_intp n, double* lo, double* hi) {
    for (int c = 0; c < 3; ++c) lo[c] = INF, hi[c] = -INF;
    for (npy_intp i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
            double x = pts[3 * i + c];
            if (x < lo[c]) lo[c] = x;
            if (x > hi[c]) hi[c] = x;
        }
    }
    for (int c = 0; c < 3; ++c)
        if (!(std::isfinite(lo[c]) && std::isfinite(hi[c]))) return false;
    return true;
}

// ------------------------------------------------------------------------------- GJK / EPA

const int64_t NO_ADJACENCY[1] = {0};

// query_points(a, b, tol, want_depth) -> (11,) float64; out[0] = -1 for non-finite input.
PyObject* query_points(PyObject*, PyObject* args) {
    PyObject *ao, *bo;
    double tol;
    int want_depth;
    if (!PyArg_ParseTuple(args, "OOdp", &ao, &bo, &tol, &want_depth)) return nullptr;
    Array a, b, res;
    if (!as_array(ao, NPY_DOUBLE, 2, 3, "a", a) || !as_array(bo, NPY_DOUBLE, 2, 3, "b", b))
        return nullptr;
    if (a.len() == 0 || b.len() == 0) {
        PyErr_SetString(PyExc_ValueError, "a, b: expected at least one point each");
        return nullptr;
    }
    npy_intp dims[1] = {11};
    res.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(1, dims, NPY_DOUBLE));
    if (res.a == nullptr) return nullptr;
    Answer out;
    double box[4][3];
    if (!bounds(a.f8(), a.len(), box[0], box[1]) || !bounds(b.f8(), b.len(), box[2], box[3])) {
        out.v[0] = -1.0;
        for (int c = 1; c < 11; ++c) out.v[c] = 0.0;
    } else {
        Frame fr = make_frame(box[0], box[1], box[2], box[3], tol);
        Shape A{a.f8(), NO_ADJACENCY, NO_ADJACENCY, 0, a.len(), false};
        Shape B{b.f8(), NO_ADJACENCY, NO_ADJACENCY, 0, b.len(), false};
        Simplex s;
        int k = gjk(A, B, fr, INF, s, out);
        if (k > 0) {
            static thread_local Polytope P;  // work space, allocated once per thread
            contact(Pair{A, B, fr, out}, s, k, want_depth != 0, P);
        }
    }
    std::copy(out.v, out.v + 11, res.f8());
    return res.release();
}

struct Batch {
    const double *points, *lower, *upper, *tols, *max_dists;
    const int64_t *starts, *nbr_starts, *nbrs, *pairs;
    bool want_depth;
    int8_t* status;
    double *distance, *point_a, *point_b, *normal;
};

// Answer pairs q0:q1 of the batch.
void run_pairs(const Batch& t, int64_t q0, int64_t q1, Polytope& P) {
    Simplex s;
    Answer out;
    for (int64_t q = q0; q < q1; ++q) {
        int64_t i = t.pairs[2 * q], j = t.pairs[2 * q + 1];
        int64_t a0 = t.starts[i], a1 = t.starts[i + 1], b0 = t.starts[j], b1 = t.starts[j + 1];
        Shape A{t.points, t.nbr_starts, t.nbrs, a0, a1, t.nbr_starts[a0 + 1] > t.nbr_starts[a0]};
        Shape B{t.points, t.nbr_starts, t.nbrs, b0, b1, t.nbr_starts[b0 + 1] > t.nbr_starts[b0]};
        Frame fr = make_frame(t.lower + 3 * i, t.upper + 3 * i, t.lower + 3 * j, t.upper + 3 * j,
                              t.tols[q]);
        int k = gjk(A, B, fr, t.max_dists[q], s, out);
        if (k > 0) contact(Pair{A, B, fr, out}, s, k, t.want_depth, P);
        t.status[q] = static_cast<int8_t>(out.v[0]);
        t.distance[q] = out.v[1];
        for (int c = 0; c < 3; ++c) {
            t.point_a[3 * q + c] = out.v[2 + c];
            t.point_b[3 * q + c] = out.v[5 + c];
            t.normal[3 * q + c] = out.v[8 + c];
        }
    }
}

// The pack's structure, checked before any index in it is followed.
bool check_pack(const Array& points, const Array& starts, const Array& nbr_starts,
                const Array& nbrs, const Array& lower, const Array& upper) {
    npy_intp n = points.len(), m = starts.len() - 1;
    const int64_t* st = starts.i8();
    const int64_t* ns = nbr_starts.i8();
    if (m < 0 || lower.len() != m || upper.len() != m || nbr_starts.len() != n + 1) {
        PyErr_SetString(PyExc_ValueError, "pack: array lengths do not match");
        return false;
    }
    for (npy_intp s = 0; s < m; ++s) {
        if (st[s] < 0 || st[s + 1] <= st[s] || st[s + 1] > n) {
            PyErr_SetString(PyExc_ValueError, "pack: shape ranges must be non-empty and in order");
            return false;
        }
    }
    for (npy_intp i = 0; i < n; ++i) {
        if (ns[i] < 0 || ns[i + 1] < ns[i] || ns[i + 1] > nbrs.len()) {
            PyErr_SetString(PyExc_ValueError, "pack: adjacency rows out of range");
            return false;
        }
    }
    return indices_in(nbrs.i8(), nbrs.len(), n, "pack.nbrs");
}

// One side of a two-pack kernel: its six arrays (points, starts, nbr_starts, nbrs, lower,
// upper) read from `o` and checked, named `side`.points and so on in errors.
struct PackArgs {
    Array points, starts, nbr_starts, nbrs, lower, upper;

    bool parse(PyObject* const* o, const char* side) {
        const std::string s(side);
        return as_array(o[0], NPY_DOUBLE, 2, 3, (s + ".points").c_str(), points) &&
               as_array(o[1], NPY_INT64, 1, 0, (s + ".starts").c_str(), starts) &&
               as_array(o[2], NPY_INT64, 1, 0, (s + ".nbr_starts").c_str(), nbr_starts) &&
               as_array(o[3], NPY_INT64, 1, 0, (s + ".nbrs").c_str(), nbrs) &&
               as_array(o[4], NPY_DOUBLE, 2, 3, (s + ".lower").c_str(), lower) &&
               as_array(o[5], NPY_DOUBLE, 2, 3, (s + ".upper").c_str(), upper) &&
               check_pack(points, starts, nbr_starts, nbrs, lower, upper);
    }
    npy_intp pieces_count() const { return starts.len() - 1; }
    Pieces pieces() const {
        return {points.f8(), starts.i8(), nbr_starts.i8(), nbrs.i8(),
                lower.f8(),  upper.f8(),  starts.len() - 1, points.len()};
    }
};

// query_pairs(points, starts, nbr_starts, nbrs, lower, upper, pairs, tols, max_dists,
//             want_depth, status, distance, point_a, point_b, normal, threads) -> None
PyObject* query_pairs(PyObject*, PyObject* args) {
    PyObject *po, *so, *nso, *no, *lo, *uo, *pairo, *to, *mo, *sto, *dso, *pao, *pbo, *nmo;
    int want_depth, threads;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOpOOOOOi", &po, &so, &nso, &no, &lo, &uo, &pairo, &to,
                          &mo, &want_depth, &sto, &dso, &pao, &pbo, &nmo, &threads))
        return nullptr;
    Array points, starts, nbr_starts, nbrs, lower, upper, pairs, tols, max_dists;
    Array status, distance, point_a, point_b, normal;
    if (!as_array(po, NPY_DOUBLE, 2, 3, "points", points) ||
        !as_array(so, NPY_INT64, 1, 0, "starts", starts) ||
        !as_array(nso, NPY_INT64, 1, 0, "nbr_starts", nbr_starts) ||
        !as_array(no, NPY_INT64, 1, 0, "nbrs", nbrs) ||
        !as_array(lo, NPY_DOUBLE, 2, 3, "lower", lower) ||
        !as_array(uo, NPY_DOUBLE, 2, 3, "upper", upper) ||
        !as_array(pairo, NPY_INT64, 2, 2, "pairs", pairs) ||
        !as_array(to, NPY_DOUBLE, 1, 0, "tols", tols) ||
        !as_array(mo, NPY_DOUBLE, 1, 0, "max_dists", max_dists) ||
        !as_array(sto, NPY_INT8, 1, 0, "status", status, true) ||
        !as_array(dso, NPY_DOUBLE, 1, 0, "distance", distance, true) ||
        !as_array(pao, NPY_DOUBLE, 2, 3, "point_a", point_a, true) ||
        !as_array(pbo, NPY_DOUBLE, 2, 3, "point_b", point_b, true) ||
        !as_array(nmo, NPY_DOUBLE, 2, 3, "normal", normal, true))
        return nullptr;
    if (!check_pack(points, starts, nbr_starts, nbrs, lower, upper)) return nullptr;
    npy_intp k = pairs.len();
    if (tols.len() != k || max_dists.len() != k || status.len() != k || distance.len() != k ||
        point_a.len() != k || point_b.len() != k || normal.len() != k) {
        PyErr_SetString(PyExc_ValueError, "query_pairs: per-pair arrays must have k rows");
        return nullptr;
    }
    if (!indices_in(pairs.i8(), 2 * k, starts.len() - 1, "pairs")) return nullptr;
    Batch t{points.f8(), lower.f8(), upper.f8(), tols.f8(), max_dists.f8(),
            starts.i8(), nbr_starts.i8(), nbrs.i8(), pairs.i8(), want_depth != 0,
            static_cast<int8_t*>(PyArray_DATA(status.a)), distance.f8(), point_a.f8(),
            point_b.f8(), normal.f8()};
    {
        const NoGil released;
        if (threads <= 1) {
            Polytope P;
            run_pairs(t, 0, k, P);
        } else {
            // Chunks handed out in turn: pairs differ widely in cost (EPA or not).
            // An exception in a worker (std::bad_alloc) stops the others and is rethrown here
            // once all are joined; a thread that cannot be started leaves the work to the rest.
            constexpr int64_t CHUNK = 32;
            std::atomic<int64_t> next{0};
            std::exception_ptr failure;
            std::mutex failure_lock;
            auto work = [&]() {
                try {
                    Polytope P;
                    for (int64_t q0; (q0 = next.fetch_add(CHUNK)) < k;)
                        run_pairs(t, q0, std::min<int64_t>(q0 + CHUNK, k), P);
                } catch (...) {
                    const std::lock_guard<std::mutex> hold(failure_lock);
                    if (!failure) failure = std::current_exception();
                    next = k;
                }
            };
            std::vector<std::thread> pool;
            try {
                pool.reserve(threads);
                for (int w = 1; w < threads; ++w) pool.emplace_back(work);
            } catch (const std::exception&) {
            }
            work();
            for (auto& th : pool) th.join();
            if (failure) std::rethrow_exception(failure);
        }
    }
    Py_RETURN_NONE;
}

// placed_distances(a: points, starts, nbr_starts, nbrs, lower, upper; b: the same, local;
//                  relative (E, 4, 4), pad_a (m_a,), pad_b (m_b,), reach (E,), settle,
//                  lowest (E,) out) -> (GJK queries, piece boxes compared)
PyObject* placed_distances_py(PyObject*, PyObject* args) {
    PyObject* o[18];
    int settle;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOOOOpO", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5],
                          &o[6], &o[7], &o[8], &o[9], &o[10], &o[11], &o[12], &o[13], &o[14],
                          &o[15], &settle, &o[16]))
        return nullptr;
    PackArgs a, b;
    Array rel, pad_a, pad_b, reach, lowest;
    if (!a.parse(o, "a") || !b.parse(o + 6, "b") ||
        !as_array(o[12], NPY_DOUBLE, 3, 0, "relative", rel) ||
        !as_array(o[13], NPY_DOUBLE, 1, 0, "pad_a", pad_a) ||
        !as_array(o[14], NPY_DOUBLE, 1, 0, "pad_b", pad_b) ||
        !as_array(o[15], NPY_DOUBLE, 1, 0, "reach", reach) ||
        !as_array(o[16], NPY_DOUBLE, 1, 0, "lowest", lowest, true))
        return nullptr;
    npy_intp count = reach.len();
    if (rel.len(0) != count || rel.len(1) != 4 || rel.len(2) != 4 || lowest.len() != count ||
        pad_a.len() != a.pieces_count() || pad_b.len() != b.pieces_count()) {
        PyErr_SetString(PyExc_ValueError, "placed_distances: array lengths do not match");
        return nullptr;
    }
    PlacedBatch t{a.pieces(), b.pieces(), rel.f8(),    pad_a.f8(),
                  pad_b.f8(), reach.f8(), settle != 0, lowest.f8()};
    PlacedWorkDone done;
    {
        const NoGil released;
        done = placed_distances(t, count);
    }
    return Py_BuildValue("LL", static_cast<long long>(done.queries),
                         static_cast<long long>(done.boxes));
}

// copied_distances(a: points, starts, nbr_starts, nbrs, lower, upper; b: the same, local;
//                  centre_a (E, 4, 4), centre_b (E, 4, 4), first (E,),
//                  ta (E, KA, 4, 4), count_a (E,), tb (E, KB, 4, 4), count_b (E,), pad_a (m_a,),
//                  pad_b (m_b,), reach (E,), settle, lowest (E,) out)
//     -> (GJK queries, piece boxes compared, copies scanned by the queries)
PyObject* copied_distances_py(PyObject*, PyObject* args) {
    PyObject* o[23];
    int settle;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOOOOOOOOOOpO", &o[0], &o[1], &o[2], &o[3], &o[4],
                          &o[5], &o[6], &o[7], &o[8], &o[9], &o[10], &o[11], &o[12], &o[13],
                          &o[14], &o[15], &o[16], &o[17], &o[18], &o[19], &o[20], &o[21],
                          &settle, &o[22]))
        return nullptr;
    PackArgs a, b;
    Array centre_a, centre_b, first, ta, ca, tb, cb, pad_a, pad_b, reach, lowest;
    if (!a.parse(o, "a") || !b.parse(o + 6, "b") ||
        !as_array(o[12], NPY_DOUBLE, 3, 0, "centre_a", centre_a) ||
        !as_array(o[13], NPY_DOUBLE, 3, 0, "centre_b", centre_b) ||
        !as_array(o[14], NPY_DOUBLE, 1, 0, "first", first) ||
        !as_array(o[15], NPY_DOUBLE, 4, 0, "ta", ta) ||
        !as_array(o[16], NPY_INT64, 1, 0, "count_a", ca) ||
        !as_array(o[17], NPY_DOUBLE, 4, 0, "tb", tb) ||
        !as_array(o[18], NPY_INT64, 1, 0, "count_b", cb) ||
        !as_array(o[19], NPY_DOUBLE, 1, 0, "pad_a", pad_a) ||
        !as_array(o[20], NPY_DOUBLE, 1, 0, "pad_b", pad_b) ||
        !as_array(o[21], NPY_DOUBLE, 1, 0, "reach", reach) ||
        !as_array(o[22], NPY_DOUBLE, 1, 0, "lowest", lowest, true))
        return nullptr;
    npy_intp count = reach.len();
    auto placements = [count](const Array& t) {
        return t.len(0) == count && t.len(PyArray_NDIM(t.a) - 2) == 4 &&
               t.len(PyArray_NDIM(t.a) - 1) == 4;
    };
    if (!placements(centre_a) || !placements(centre_b) || !placements(ta) || !placements(tb) ||
        first.len() != count || ca.len() != count || cb.len() != count ||
        lowest.len() != count || pad_a.len() != a.pieces_count() ||
        pad_b.len() != b.pieces_count()) {
        PyErr_SetString(PyExc_ValueError, "copied_distances: array lengths do not match");
        return nullptr;
    }
    CopiedBatch t{a.pieces(), b.pieces(), centre_a.f8(), centre_b.f8(), first.f8(),
                  ta.f8(),    tb.f8(),    ca.i8(),       cb.i8(),       ta.len(1),
                  tb.len(1),  pad_a.f8(), pad_b.f8(),    reach.f8(),    settle != 0,
                  lowest.f8()};
    PlacedWorkDone done;
    {
        const NoGil released;
        done = copied_distances(t, count);
    }
    return Py_BuildValue("LLL", static_cast<long long>(done.queries),
                         static_cast<long long>(done.boxes),
                         static_cast<long long>(done.supports));
}

// hull_levers(hull (k, 3), placed (E, 4, 4), points (E, T, 3), directions (E, T, 3)) -> (E, T)
PyObject* hull_levers_py(PyObject*, PyObject* args) {
    PyObject *ho, *po, *lo, *do_;
    if (!PyArg_ParseTuple(args, "OOOO", &ho, &po, &lo, &do_)) return nullptr;
    Array hull, placed, points, dirs, out;
    if (!as_array(ho, NPY_DOUBLE, 2, 3, "hull", hull) ||
        !as_array(po, NPY_DOUBLE, 3, 0, "placed", placed) ||
        !as_array(lo, NPY_DOUBLE, 3, 0, "points", points) ||
        !as_array(do_, NPY_DOUBLE, 3, 0, "directions", dirs))
        return nullptr;
    npy_intp count = placed.len(0), lines = points.len(1);
    if (placed.len(1) != 4 || placed.len(2) != 4 || points.len(0) != count ||
        points.len(2) != 3 || dirs.len(0) != count || dirs.len(1) != lines ||
        dirs.len(2) != 3) {
        PyErr_SetString(PyExc_ValueError, "hull_levers: array shapes do not match");
        return nullptr;
    }
    npy_intp dims[2] = {count, lines};
    out.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(2, dims, NPY_DOUBLE));
    if (out.a == nullptr) return nullptr;
    {
        const NoGil released;
        hull_levers(hull.f8(), hull.len(), placed.f8(), points.f8(), dirs.f8(), count, lines,
                    out.f8());
    }
    return out.release();
}

// chain_placements(before (J, 4, 4), kinds (J,), axes (J, 3), after (4, 4), values (E, J),
// scale) -> (placed (E, 4, 4), points (E, J, 3), directions (E, J, 3))
PyObject* chain_placements_py(PyObject*, PyObject* args) {
    PyObject *bo, *ko, *ao, *fo, *vo;
    double scale;
    if (!PyArg_ParseTuple(args, "OOOOOd", &bo, &ko, &ao, &fo, &vo, &scale)) return nullptr;
    Array before, kinds, axes, after, values, out, points, directions;
    if (!as_array(bo, NPY_DOUBLE, 3, 0, "before", before) ||
        !as_array(ko, NPY_INT64, 1, 0, "kinds", kinds) ||
        !as_array(ao, NPY_DOUBLE, 2, 3, "axes", axes) ||
        !as_array(fo, NPY_DOUBLE, 2, 4, "after", after) ||
        !as_array(vo, NPY_DOUBLE, 2, kinds.len(), "values", values))
        return nullptr;
    npy_intp joints = kinds.len(), count = values.len(0);
    if (before.len(0) != joints || before.len(1) != 4 || before.len(2) != 4 ||
        axes.len() != joints || after.len() != 4) {
        PyErr_SetString(PyExc_ValueError, "chain_placements: array shapes do not match");
        return nullptr;
    }
    for (npy_intp j = 0; j < joints; ++j) {
        if (kinds.i8()[j] != 0 && kinds.i8()[j] != 1) {
            PyErr_SetString(PyExc_ValueError, "kinds: expected 0 (turn) or 1 (slide)");
            return nullptr;
        }
    }
    npy_intp placed_dims[3] = {count, 4, 4}, line_dims[3] = {count, joints, 3};
    out.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(3, placed_dims, NPY_DOUBLE));
    if (out.a == nullptr) return nullptr;
    points.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(3, line_dims, NPY_DOUBLE));
    if (points.a == nullptr) return nullptr;
    directions.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(3, line_dims, NPY_DOUBLE));
    if (directions.a == nullptr) return nullptr;
    {
        const NoGil released;
        chain_placements(before.f8(), kinds.i8(), axes.f8(), after.f8(), values.f8(), count,
                         joints, scale, out.f8(), points.f8(), directions.f8());
    }
    return Py_BuildValue("NNN", out.release(), points.release(), directions.release());
}

// Two meshes and the (4, 4) placement of the second in the first's frame.
bool placed_meshes(PyObject* vao, PyObject* fao, PyObject* vbo, PyObject* fbo, PyObject* to,
                   Array& va, Array& fa, Array& vb, Array& fb, Array& t) {
    if (!as_array(vao, NPY_DOUBLE, 2, 3, "va", va) || !faces_of(fao, va.len(), "fa", fa) ||
        !as_array(vbo, NPY_DOUBLE, 2, 3, "vb", vb) || !faces_of(fbo, vb.len(), "fb", fb) ||
        !as_array(to, NPY_DOUBLE, 2, 4, "relative", t))
        return false;
    if (t.len() != 4) {
        PyErr_SetString(PyExc_ValueError, "relative: expected a (4, 4) array");
        return false;
    }
    return true;
}

// placed_surface_distance(va, fa, vb, fb, relative (4, 4), reach, settle) -> (distance, pairs)
PyObject* placed_surface_distance_py(PyObject*, PyObject* args) {
    PyObject *vao, *fao, *vbo, *fbo, *to;
    double reach;
    int settle;
    if (!PyArg_ParseTuple(args, "OOOOOdp", &vao, &fao, &vbo, &fbo, &to, &reach, &settle))
        return nullptr;
    Array va, fa, vb, fb, t;
    if (!placed_meshes(vao, fao, vbo, fbo, to, va, fa, vb, fb, t)) return nullptr;
    int64_t work = 0;
    double d;
    {
        const NoGil released;
        d = placed_surface_distance(va.f8(), fa.i8(), fa.len(), vb.f8(), vb.len(), fb.i8(),
                                    fb.len(), t.f8(), reach, settle != 0, work);
    }
    return Py_BuildValue("dL", d, static_cast<long long>(work));
}

// ------------------------------------------------------------------------------- triangles

// triangle_boxes(v, f) -> (lower, upper)
PyObject* triangle_boxes_py(PyObject*, PyObject* args) {
    PyObject *vo, *fo;
    if (!PyArg_ParseTuple(args, "OO", &vo, &fo)) return nullptr;
    Array v, f, lo, hi;
    if (!as_array(vo, NPY_DOUBLE, 2, 3, "v", v) || !faces_of(fo, v.len(), "f", f)) return nullptr;
    if (!new_array(2, f.len(), NPY_DOUBLE, lo) || !new_array(2, f.len(), NPY_DOUBLE, hi))
        return nullptr;
    triangle_boxes(v.f8(), f.i8(), f.len(), lo.f8(), hi.f8());
    return Py_BuildValue("NN", lo.release(), hi.release());
}

// box_pairs(alo, ahi, blo, bhi, reach) -> (k, 2) int64
PyObject* box_pairs_py(PyObject*, PyObject* args) {
    PyObject *alo_o, *ahi_o, *blo_o, *bhi_o;
    double reach;
    if (!PyArg_ParseTuple(args, "OOOOd", &alo_o, &ahi_o, &blo_o, &bhi_o, &reach)) return nullptr;
    Array alo, ahi, blo, bhi, res;
    if (!as_array(alo_o, NPY_DOUBLE, 2, 3, "alo", alo) ||
        !as_array(ahi_o, NPY_DOUBLE, 2, 3, "ahi", ahi) ||
        !as_array(blo_o, NPY_DOUBLE, 2, 3, "blo", blo) ||
        !as_array(bhi_o, NPY_DOUBLE, 2, 3, "bhi", bhi))
        return nullptr;
    if (alo.len() != ahi.len() || blo.len() != bhi.len()) {
        PyErr_SetString(PyExc_ValueError, "box_pairs: lower and upper differ in length");
        return nullptr;
    }
    std::vector<int64_t> out;
    {
        const NoGil released;
        box_pairs(alo.f8(), ahi.f8(), alo.len(), blo.f8(), bhi.f8(), blo.len(), reach, out);
    }
    npy_intp dims[2] = {static_cast<npy_intp>(out.size() / 2), 2};
    res.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(2, dims, NPY_INT64));
    if (res.a == nullptr) return nullptr;
    std::copy(out.begin(), out.end(), res.i8());
    return res.release();
}

// near_triangle_pairs(va, fa, vb, fb, relative (4, 4), reach) -> pairs (k, 2)
PyObject* near_triangle_pairs_py(PyObject*, PyObject* args) {
    PyObject *vao, *fao, *vbo, *fbo, *to;
    double reach;
    if (!PyArg_ParseTuple(args, "OOOOOd", &vao, &fao, &vbo, &fbo, &to, &reach)) return nullptr;
    Array va, fa, vb, fb, t, res;
    if (!placed_meshes(vao, fao, vbo, fbo, to, va, fa, vb, fb, t)) return nullptr;
    for (int c = 0; c < 12; ++c) {
        if (!std::isfinite(t.f8()[c])) {
            PyErr_SetString(PyExc_ValueError, "relative: not finite");
            return nullptr;
        }
    }
    if (std::isnan(reach)) {
        PyErr_SetString(PyExc_ValueError, "reach: not a number");
        return nullptr;
    }
    NearTriangles near;
    {
        const NoGil released;
        near_triangle_pairs(va.f8(), fa.i8(), fa.len(), vb.f8(), vb.len(), fb.i8(), fb.len(),
                            t.f8(), reach, near);
    }
    npy_intp dims[2] = {static_cast<npy_intp>(near.pairs.size() / 2), 2};
    res.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(2, dims, NPY_INT64));
    if (res.a == nullptr) return nullptr;
    std::copy(near.pairs.begin(), near.pairs.end(), res.i8());
    return res.release();
}

// pair_distances(va, fa, vb, fb, pairs) -> (distance, point_a, point_b, strength)
PyObject* pair_distances_py(PyObject*, PyObject* args) {
    PyObject *vao, *fao, *vbo, *fbo, *po;
    if (!PyArg_ParseTuple(args, "OOOOO", &vao, &fao, &vbo, &fbo, &po)) return nullptr;
    Array va, fa, vb, fb, pairs, dist, pa, pb, strength;
    if (!as_array(vao, NPY_DOUBLE, 2, 3, "va", va) || !faces_of(fao, va.len(), "fa", fa) ||
        !as_array(vbo, NPY_DOUBLE, 2, 3, "vb", vb) || !faces_of(fbo, vb.len(), "fb", fb) ||
        !as_array(po, NPY_INT64, 2, 2, "pairs", pairs))
        return nullptr;
    npy_intp k = pairs.len();
    const int64_t* pr = pairs.i8();
    for (npy_intp t = 0; t < k; ++t) {
        if (pr[2 * t] < 0 || pr[2 * t] >= fa.len() || pr[2 * t + 1] < 0 ||
            pr[2 * t + 1] >= fb.len()) {
            PyErr_SetString(PyExc_ValueError, "pairs: face index out of range");
            return nullptr;
        }
    }
    if (!new_array(1, k, NPY_DOUBLE, dist) || !new_array(2, k, NPY_DOUBLE, pa) ||
        !new_array(2, k, NPY_DOUBLE, pb) || !new_array(1, k, NPY_DOUBLE, strength))
        return nullptr;
    {
        const NoGil released;
        for (npy_intp t = 0; t < k; ++t) {
            Tri ta = triangle(va.f8(), fa.i8(), pr[2 * t]);
            Tri tb = triangle(vb.f8(), fb.i8(), pr[2 * t + 1]);
            V3 x, y;
            bool crossing;
            dist.f8()[t] = triangle_distance(ta, tb, x, y, crossing);
            double* px = pa.f8() + 3 * t;
            double* py = pb.f8() + 3 * t;
            px[0] = x.x, px[1] = x.y, px[2] = x.z;
            py[0] = y.x, py[1] = y.y, py[2] = y.z;
            strength.f8()[t] = crossing ? crossing_strength(ta, tb) : 0.0;
        }
    }
    return Py_BuildValue("NNNN", dist.release(), pa.release(), pb.release(), strength.release());
}

bool point3(PyObject* o, V3& p) {
    Array a;
    if (!as_array(o, NPY_DOUBLE, 1, 0, "point", a)) return false;
    if (a.len() != 3) {
        PyErr_SetString(PyExc_ValueError, "point: expected 3 coordinates");
        return false;
    }
    p = {a.f8()[0], a.f8()[1], a.f8()[2]};
    return true;
}

PyObject* tuple3(V3 p) { return Py_BuildValue("(ddd)", p.x, p.y, p.z); }

// triangle_distance(a0, a1, a2, b0, b1, b2) -> (distance, point_a, point_b, crossing)
PyObject* triangle_distance_py(PyObject*, PyObject* args) {
    PyObject* o[6];
    if (!PyArg_ParseTuple(args, "OOOOOO", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5]))
        return nullptr;
    Tri ta, tb;
    for (int i = 0; i < 3; ++i)
        if (!point3(o[i], ta.p[i]) || !point3(o[3 + i], tb.p[i])) return nullptr;
    V3 x, y;
    bool crossing;
    double d = triangle_distance(ta, tb, x, y, crossing);
    return Py_BuildValue("dNNO", d, tuple3(x), tuple3(y), crossing ? Py_True : Py_False);
}

// Points (k, 3) against a mesh: fn(point, v, f, m) for each point -> (k,) float64.
template <double (*fn)(V3, const double*, const int64_t*, int64_t)>
PyObject* per_point(PyObject*, PyObject* args) {
    PyObject *po, *vo, *fo;
    if (!PyArg_ParseTuple(args, "OOO", &po, &vo, &fo)) return nullptr;
    Array pts, v, f, res;
    if (!as_array(po, NPY_DOUBLE, 2, 3, "points", pts) || !as_array(vo, NPY_DOUBLE, 2, 3, "v", v) ||
        !faces_of(fo, v.len(), "f", f) || !new_array(1, pts.len(), NPY_DOUBLE, res))
        return nullptr;
    {
        const NoGil released;
        for (npy_intp i = 0; i < pts.len(); ++i)
            res.f8()[i] = fn(row(pts.f8(), i), v.f8(), f.i8(), f.len());
    }
    return res.release();
}

// inscribed_ball(v, f, max_seeds) -> (radius, (x, y, z))
PyObject* inscribed_ball_py(PyObject*, PyObject* args) {
    PyObject *vo, *fo;
    long long max_seeds;
    if (!PyArg_ParseTuple(args, "OOL", &vo, &fo, &max_seeds)) return nullptr;
    Array v, f;
    if (!as_array(vo, NPY_DOUBLE, 2, 3, "v", v) || !faces_of(fo, v.len(), "f", f)) return nullptr;
    if (max_seeds < 1) {
        PyErr_SetString(PyExc_ValueError, "max_seeds must be >= 1");
        return nullptr;
    }
    V3 x;
    double r;
    {
        const NoGil released;
        r = inscribed_ball(v.f8(), f.i8(), f.len(), max_seeds, x);
    }
    return Py_BuildValue("dN", r, tuple3(x));
}

// ray_hits(o (r, 3), d (r, 3), v, f, beyond) -> (r,) float64: each ray's first hit beyond `beyond`.
PyObject* ray_hits_py(PyObject*, PyObject* args) {
    PyObject *oo, *dobj, *vo, *fo;
    double beyond;
    if (!PyArg_ParseTuple(args, "OOOOd", &oo, &dobj, &vo, &fo, &beyond)) return nullptr;
    Array o, d, v, f, res;
    if (!as_array(oo, NPY_DOUBLE, 2, 3, "o", o) || !as_array(dobj, NPY_DOUBLE, 2, 3, "d", d) ||
        !as_array(vo, NPY_DOUBLE, 2, 3, "v", v) || !faces_of(fo, v.len(), "f", f))
        return nullptr;
    if (o.len() != d.len()) {
        PyErr_SetString(PyExc_ValueError, "d: expected one direction per origin");
        return nullptr;
    }
    if (!new_array(1, o.len(), NPY_DOUBLE, res)) return nullptr;
    {
        const NoGil released;
        const MeshBvh bvh(v.f8(), f.i8(), f.len());
        for (npy_intp i = 0; i < o.len(); ++i)
            res.f8()[i] = bvh_ray_first_hit(bvh, row(o.f8(), i), row(d.f8(), i), -1, beyond);
    }
    return res.release();
}

// ball_lp(p (m, 3), h (m,), R, max_iter) -> (status, x (3,) , t, y (m + 6,)); see lp.hpp.
PyObject* ball_lp_py(PyObject*, PyObject* args) {
    PyObject *po, *ho;
    double R;
    long long max_iter;
    if (!PyArg_ParseTuple(args, "OOdL", &po, &ho, &R, &max_iter)) return nullptr;
    Array p, h, x, y;
    if (!as_array(po, NPY_DOUBLE, 2, 3, "p", p) || !as_array(ho, NPY_DOUBLE, 1, 0, "h", h))
        return nullptr;
    if (h.len() != p.len()) {
        PyErr_SetString(PyExc_ValueError, "h: expected one value per row of p");
        return nullptr;
    }
    npy_intp n = p.len() + 6, three = 3;
    x.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(1, &three, NPY_DOUBLE));
    if (x.a == nullptr) return nullptr;
    y.a = reinterpret_cast<PyArrayObject*>(PyArray_SimpleNew(1, &n, NPY_DOUBLE));
    if (y.a == nullptr) return nullptr;
    double t;
    int status;
    {
        const NoGil released;
        status = ball_lp(p.f8(), h.f8(), p.len(), R, max_iter, x.f8(), t, y.f8());
    }
    return Py_BuildValue("iNdN", status, x.release(), t, y.release());
}

// closest_points_on_triangles(p, v, f) -> (distance (m,), points (m, 3))
PyObject* closest_points_on_triangles_py(PyObject*, PyObject* args) {
    PyObject *po, *vo, *fo;
    if (!PyArg_ParseTuple(args, "OOO", &po, &vo, &fo)) return nullptr;
    V3 p;
    Array v, f, dist, q;
    if (!point3(po, p) || !as_array(vo, NPY_DOUBLE, 2, 3, "v", v) ||
        !faces_of(fo, v.len(), "f", f) || !new_array(1, f.len(), NPY_DOUBLE, dist) ||
        !new_array(2, f.len(), NPY_DOUBLE, q))
        return nullptr;
    {
        const NoGil released;
        for (npy_intp k = 0; k < f.len(); ++k) {
            V3 y = closest_on_tri(p, triangle(v.f8(), f.i8(), k));
            dist.f8()[k] = std::sqrt(dist2(p, y));
            double* out = q.f8() + 3 * k;
            out[0] = y.x, out[1] = y.y, out[2] = y.z;
        }
    }
    return Py_BuildValue("NN", dist.release(), q.release());
}

// ------------------------------------------------------------------------------- module

// The tolerances come from meshcheck/geometry/constants.py, where each is explained.
bool read_constants() {
    PyObject* mod = PyImport_ImportModule("meshcheck.geometry.constants");
    if (mod == nullptr) return false;
    bool ok = true;
    auto real = [&](const char* name) {
        PyObject* o = PyObject_GetAttrString(mod, name);
        double x = o ? PyFloat_AsDouble(o) : -1.0;
        Py_XDECREF(o);
        if (PyErr_Occurred()) ok = false;
        return x;
    };
    auto integer = [&](const char* name) {
        PyObject* o = PyObject_GetAttrString(mod, name);
        long long x = o ? PyLong_AsLongLong(o) : -1;
        Py_XDECREF(o);
        if (PyErr_Occurred()) ok = false;
        return x;
    };
    K.touch_rel = real("TOUCH_REL");
    K.coord_rel = real("COORD_REL");
    K.gjk_rel_gap = real("GJK_REL_GAP");
    K.zero_rel = real("ZERO_REL");
    K.degenerate_sin = real("DEGENERATE_SIN");
    K.epa_rel_gap = real("EPA_REL_GAP");
    K.gjk_max_iter = integer("GJK_MAX_ITER");
    K.epa_max_iter = integer("EPA_MAX_ITER");
    K.separated = static_cast<int>(integer("SEPARATED"));
    K.touching = static_cast<int>(integer("TOUCHING"));
    K.penetrating = static_cast<int>(integer("PENETRATING"));
    K.undecided = static_cast<int>(integer("UNDECIDED"));
    Py_DECREF(mod);
    return ok;
}

double winding_number_fn(V3 p, const double* v, const int64_t* f, int64_t m) {
    return winding_number(p, v, f, m);
}
double point_distance_fn(V3 p, const double* v, const int64_t* f, int64_t m) {
    return point_mesh_distance(p, v, f, m);
}

// point_distances(points (k, 3), v, f) -> (k,) float64: through a BVH when there are enough points
// to repay building it (the same values, bit for bit; see MeshBvh).
PyObject* point_distances_py(PyObject* self, PyObject* args) {
    PyObject *po, *vo, *fo;
    if (!PyArg_ParseTuple(args, "OOO", &po, &vo, &fo)) return nullptr;
    Array pts, v, f, res;
    if (!as_array(po, NPY_DOUBLE, 2, 3, "points", pts) || !as_array(vo, NPY_DOUBLE, 2, 3, "v", v) ||
        !faces_of(fo, v.len(), "f", f))
        return nullptr;
    if (pts.len() < 8 || f.len() < 64) return per_point<point_distance_fn>(self, args);
    if (!new_array(1, pts.len(), NPY_DOUBLE, res)) return nullptr;
    {
        const NoGil released;
        const MeshBvh bvh(v.f8(), f.i8(), f.len());
        for (npy_intp i = 0; i < pts.len(); ++i) {
            int64_t no_hint = -1;
            res.f8()[i] = bvh_distance_beyond(bvh, row(pts.f8(), i), -1.0, no_hint);
        }
    }
    return res.release();
}

// group_rows(keys (n, c) int64, by_sorting) -> (first (g,) int64, inverse (n,) int64)
PyObject* group_rows_py(PyObject*, PyObject* args) {
    PyObject* ko;
    int by_sorting = 0;
    if (!PyArg_ParseTuple(args, "O|p", &ko, &by_sorting)) return nullptr;
    Array k, inverse, first;
    k.a = reinterpret_cast<PyArrayObject*>(
        PyArray_FROMANY(ko, NPY_INT64, 2, 2, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (k.a == nullptr || !new_array(1, k.len(), NPY_INT64, inverse)) return nullptr;
    const int64_t cols = k.len(1);
    std::vector<int64_t> heads;
    {
        const NoGil released;
        if (by_sorting)
            group_rows_sorted(k.i8(), k.len(), cols, inverse.i8(), heads);
        else
            group_rows(k.i8(), k.len(), cols, inverse.i8(), heads);
    }
    if (!new_array(1, static_cast<npy_intp>(heads.size()), NPY_INT64, first)) return nullptr;
    std::copy(heads.begin(), heads.end(), first.i8());
    return Py_BuildValue("NN", first.release(), inverse.release());
}

// degenerate_triangles(v, f) -> (repeated (m,) bool, flat (m,) bool)
PyObject* degenerate_triangles_py(PyObject*, PyObject* args) {
    PyObject *vo, *fo;
    if (!PyArg_ParseTuple(args, "OO", &vo, &fo)) return nullptr;
    Array v, f, repeated, flat;
    if (!as_array(vo, NPY_DOUBLE, 2, 3, "v", v) || !faces_of(fo, v.len(), "f", f) ||
        !new_array(1, f.len(), NPY_BOOL, repeated) || !new_array(1, f.len(), NPY_BOOL, flat))
        return nullptr;
    {
        const NoGil released;
        degenerate_triangles(v.f8(), f.i8(), f.len(), static_cast<bool*>(PyArray_DATA(repeated.a)),
                             static_cast<bool*>(PyArray_DATA(flat.a)));
    }
    return Py_BuildValue("NN", repeated.release(), flat.release());
}

// is_closed(faces (m, 3) int64) -> bool
PyObject* is_closed_py(PyObject*, PyObject* args) {
    PyObject* fo;
    if (!PyArg_ParseTuple(args, "O", &fo)) return nullptr;
    Array f;
    if (!as_array(fo, NPY_INT64, 2, 3, "faces", f)) return nullptr;
    bool closed;
    {
        const NoGil released;
        closed = is_closed(f.i8(), f.len());
    }
    return PyBool_FromLong(closed);
}

// shell_labels(faces (m, 3) int64, n_vertices) -> (labels (m,) int64, count)
PyObject* shell_labels_py(PyObject*, PyObject* args) {
    PyObject* fo;
    long long n_vertices;
    if (!PyArg_ParseTuple(args, "OL", &fo, &n_vertices)) return nullptr;
    Array f, labels;
    if (n_vertices < 0) {
        PyErr_SetString(PyExc_ValueError, "n_vertices must be >= 0");
        return nullptr;
    }
    if (!faces_of(fo, static_cast<npy_intp>(n_vertices), "faces", f) ||
        !new_array(1, f.len(), NPY_INT64, labels))
        return nullptr;
    int64_t count;
    {
        const NoGil released;
        count = shell_labels(f.i8(), f.len(), n_vertices, labels.i8());
    }
    return Py_BuildValue("NL", labels.release(), static_cast<long long>(count));
}

PyMethodDef METHODS[] = {
    {"query_points", guarded<query_points>, METH_VARARGS, nullptr},
    {"query_pairs", guarded<query_pairs>, METH_VARARGS, nullptr},
    {"placed_distances", guarded<placed_distances_py>, METH_VARARGS, nullptr},
    {"copied_distances", guarded<copied_distances_py>, METH_VARARGS, nullptr},
    {"hull_levers", guarded<hull_levers_py>, METH_VARARGS, nullptr},
    {"chain_placements", guarded<chain_placements_py>, METH_VARARGS, nullptr},
    {"placed_surface_distance", guarded<placed_surface_distance_py>, METH_VARARGS, nullptr},
    {"triangle_boxes", guarded<triangle_boxes_py>, METH_VARARGS, nullptr},
    {"box_pairs", guarded<box_pairs_py>, METH_VARARGS, nullptr},
    {"near_triangle_pairs", guarded<near_triangle_pairs_py>, METH_VARARGS, nullptr},
    {"pair_distances", guarded<pair_distances_py>, METH_VARARGS, nullptr},
    {"triangle_distance", guarded<triangle_distance_py>, METH_VARARGS, nullptr},
    {"winding_numbers", guarded<per_point<winding_number_fn>>, METH_VARARGS, nullptr},
    {"point_distances", guarded<point_distances_py>, METH_VARARGS, nullptr},
    {"inscribed_ball", guarded<inscribed_ball_py>, METH_VARARGS, nullptr},
    {"ball_lp", guarded<ball_lp_py>, METH_VARARGS, nullptr},
    {"ray_hits", guarded<ray_hits_py>, METH_VARARGS, nullptr},
    {"closest_points_on_triangles", guarded<closest_points_on_triangles_py>, METH_VARARGS, nullptr},
    {"group_rows", guarded<group_rows_py>, METH_VARARGS, nullptr},
    {"degenerate_triangles", guarded<degenerate_triangles_py>, METH_VARARGS, nullptr},
    {"is_closed", guarded<is_closed_py>, METH_VARARGS, nullptr},
    {"shell_labels", guarded<shell_labels_py>, METH_VARARGS, nullptr},
    {nullptr, nullptr, 0, nullptr},
};

PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_kernels", nullptr, -1, METHODS,
                      nullptr, nullptr, nullptr, nullptr};

}  // namespace

PyMODINIT_FUNC PyInit__kernels() {
    import_array();
    if (!read_constants()) return nullptr;
    return PyModule_Create(&MODULE);
}
