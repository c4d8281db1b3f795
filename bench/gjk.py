"""GJK kernel against python-fcl on random convex hull pairs.

Command::

    python bench/gjk.py

(options: ``--pairs N`` pairs, ``--vertices V`` per hull, ``--rounds R``, ``--seed S``).

Both sides get the same hulls: V points on a random ellipsoid (all of them hull vertices),
pairs placed so that about half overlap. FCL gets ``fcl.Convex`` collision objects built
beforehand (faces from Qhull), and is called with ``fcl.distance`` and
``DistanceRequest(enable_nearest_points=True)``, GJK solver defaults; meshcheck is timed as

* ``signed_distance(a, b)`` per call on the raw (V, 3) point arrays (no hull, linear scan);
* ``query_pairs(pack, pairs)`` once for all pairs, on a pack built beforehand, with the
  penetration depth (``depth=True``) and without it (``depth=False``), in one thread
  (``threads=1``) and on one thread per core (``threads=0``).

Rounds alternate between the contenders in one process, after a warm-up round; the figures are
medians over rounds, per pair: wall time, and CPU time of the process (all its threads), which
a machine shared with other work disturbs much less (for the threaded rows CPU time shows the
cost, wall time the speed-up). Note the work differs
on overlapping pairs: FCL with the requested defaults (``enable_signed_distance=False``) stops
at "colliding" and returns -1, while ``signed_distance`` and ``query_pairs(depth=True)`` also
measure the depth with EPA; FCL with ``enable_signed_distance=True`` is listed for that
comparison (ratios are all against the default FCL row). Separated pairs are also checked for
agreement of the distances.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from meshcheck.geometry import pack_convex, query_pairs, signed_distance


def make_hulls(n_pairs: int, n_vertices: int, seed: int) -> tuple[list, list]:
    """Random ellipsoid point sets, unit-ish size, pairs at distances from -0.8 to 1.2."""
    rng = np.random.default_rng(seed)

    def hull(centre):
        p = rng.normal(size=(n_vertices, 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        p *= rng.uniform(0.4, 1.0, size=3)
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        return np.ascontiguousarray(p @ rot.T + centre)

    a_list, b_list = [], []
    for _ in range(n_pairs):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        a_list.append(hull(np.zeros(3)))
        b_list.append(hull(direction * rng.uniform(0.6, 3.0)))
    return a_list, b_list


def fcl_object(fcl, points):
    hull = ConvexHull(points)
    tris = hull.simplices
    faces = np.hstack([np.full((len(tris), 1), 3), tris]).ravel()
    return fcl.CollisionObject(fcl.Convex(points, len(tris), faces), fcl.Transform())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=2000)
    parser.add_argument("--vertices", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--seed", type=int, default=20240611)
    args = parser.parse_args()
    try:
        import fcl
    except ImportError:
        sys.exit("error: python-fcl is not installed (pip install python-fcl)")

    a_list, b_list = make_hulls(args.pairs, args.vertices, args.seed)
    n = args.pairs
    fcl_pairs = [
        (fcl_object(fcl, a), fcl_object(fcl, b)) for a, b in zip(a_list, b_list, strict=True)
    ]
    request = fcl.DistanceRequest(enable_nearest_points=True)
    pack = pack_convex(a_list + b_list)
    pairs = np.stack([np.arange(n), np.arange(n) + n], axis=1).astype(np.int64)
    tolerance = 1e-9

    def run_fcl():
        out = np.empty(n)
        for k, (oa, ob) in enumerate(fcl_pairs):
            out[k] = fcl.distance(oa, ob, request, fcl.DistanceResult())
        return out

    signed_request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)

    def run_fcl_signed():
        out = np.empty(n)
        for k, (oa, ob) in enumerate(fcl_pairs):
            out[k] = fcl.distance(oa, ob, signed_request, fcl.DistanceResult())
        return out

    def run_single():
        out = np.empty(n)
        for k in range(n):
            out[k] = signed_distance(a_list[k], b_list[k], tolerance=tolerance)
        return out

    def batch(depth: bool, threads: int):
        def run():
            return query_pairs(
                pack, pairs, tolerance=tolerance, depth=depth, threads=threads
            ).distance

        return run

    threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1
    contenders = {
        "fcl.distance per call": run_fcl,
        "  fcl, enable_signed_distance": run_fcl_signed,
        "signed_distance per call": run_single,
        "query_pairs depth=True": batch(True, 1),
        "query_pairs depth=False": batch(False, 1),
        f"  same, {threads} threads, depth=True": batch(True, 0),
        f"  same, {threads} threads, depth=False": batch(False, 0),
    }
    results = {name: f() for name, f in contenders.items()}  # warm-up
    times: dict[str, list[float]] = {name: [] for name in contenders}
    cpu: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(args.rounds):
        for name, f in contenders.items():
            t0, c0 = time.perf_counter(), time.process_time()
            f()
            times[name].append((time.perf_counter() - t0) / n)
            cpu[name].append((time.process_time() - c0) / n)

    d_fcl = results["fcl.distance per call"]
    d_ours = results["signed_distance per call"]
    sep = d_ours > 0
    agree = np.abs(d_fcl[sep] - d_ours[sep])
    print(
        f"python {platform.python_version()}, numpy {np.__version__}, "
        f"fcl {fcl.__version__}, {os.cpu_count()} cores"
    )
    print(
        f"{n} hull pairs x {args.vertices} vertices, seed {args.seed}: "
        f"{sep.sum()} separated, {(~sep).sum()} touching or overlapping; "
        f"{args.rounds} alternating rounds, median per pair"
    )
    print(
        f"separated pairs: max |fcl - meshcheck| distance {agree.max():.2e}; "
        f"fcl reports {np.sum(d_fcl[~sep] < 0)} of the rest as colliding (-1)"
    )
    batch_same = max(
        np.abs(results[name] - d_ours).max() for name in contenders if "depth=True" in name
    )
    print(f"query_pairs vs signed_distance: max |difference| {batch_same:.2e}")
    d_signed = results["  fcl, enable_signed_distance"]
    depth_gap = np.abs(d_signed[~sep] - d_ours[~sep])
    print(
        "overlapping pairs, fcl signed distance vs meshcheck depth: "
        f"median |difference| {np.median(depth_gap):.2e}, max {depth_gap.max():.2e}"
    )
    print()
    base = statistics.median(times["fcl.distance per call"])
    base_cpu = statistics.median(cpu["fcl.distance per call"])
    print(f"{'':<34}{'wall':>22}{'CPU (all threads)':>24}")
    print(
        f"{'contender':<34}{'us / pair':>10}{'fcl / this':>12}{'us / pair':>12}{'fcl / this':>12}"
    )
    for name in contenders:
        t = statistics.median(times[name])
        c = statistics.median(cpu[name])
        print(f"{name:<34}{t * 1e6:>10.2f}{base / t:>11.2f}x{c * 1e6:>12.2f}{base_cpu / c:>11.2f}x")


if __name__ == "__main__":
    main()
