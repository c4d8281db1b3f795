"""Interference depth against a simpler estimate, same process: error against closed-form answers
on thin overlaps, and time.

Run from the repository root: python bench/depth.py
"simple" is an uncertified estimate (inward-ray seeds, compass search, one successive-LP ascent:
what meshcheck 0.1 reported), kept below so both run on the same shared solids; "meshcheck" is
``verify.depth.depth_bounds``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linprog

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from depth_shapes import annulus, crescent, pin, prism_tube, tilted_slab_pair, wedge

from meshcheck.geometry.triangles import closest_points_on_triangles, inscribed_ball
from meshcheck.load import load_bodies
from meshcheck.verify.depth import depth_bounds
from meshcheck.verify.pair import outward_faces, shared_solid, verify_pair


def simple_depth(v, f):
    """The simple estimate (``solid_depth`` of meshcheck 0.1, commit 8238314)."""
    extent = float((v.max(axis=0) - v.min(axis=0)).min())
    a, b, c = v[f[:, 0]] - v[0], v[f[:, 1]] - v[0], v[f[:, 2]] - v[0]
    volume = float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0
    bound = min(extent, (6.0 * max(volume, 0.0) / math.pi) ** (1.0 / 3.0))
    radius, centre = inscribed_ball(v, f, 1024)
    if radius <= 0.0:
        return 0.0
    x, r = np.asarray(centre, dtype=np.float64), radius
    for _ in range(30):
        dist, q = closest_points_on_triangles(x, v, f)
        r = float(dist.min())
        keep = dist <= r * (1.0 + 2.0 * math.sqrt(3.0)) + 1e-300
        u = (x - q[keep]) / dist[keep, None]
        lp = linprog(
            [0.0, 0.0, 0.0, -1.0],
            A_ub=np.c_[-u, np.ones(len(u))],
            b_ub=np.einsum("ij,ij->i", u, x - q[keep]),
            bounds=[(-r, r)] * 3 + [(None, None)],
            method="highs",
        )
        if lp.status != 0:
            break
        y = x + lp.x[:3]
        ry = float(closest_points_on_triangles(y, v, f)[0].min())
        if ry <= r * (1.0 + 1e-9):
            break
        x, r = y, ry
    return min(2.0 * r, bound)


def solid_of(a, b):
    va, vb = np.asarray(a.vertices, float), np.asarray(b.vertices, float)
    origin = 0.5 * (np.maximum(va.min(0), vb.min(0)) + np.minimum(va.max(0), vb.max(0)))
    va, vb = va - origin, vb - origin
    fa, fb = outward_faces(va, np.asarray(a.faces)), outward_faces(vb, np.asarray(b.faces))
    return shared_solid(va, fa, vb, fb)


def best_ms(fn, repeat=5):
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * min(times)


def thin_cases():
    for scale in (1e-3, 1.0, 1e3):
        for n in (16, 24, 64):
            for e in (0.1, 0.02):
                yield f"shell e={e} n={n} x{scale:g}", annulus(scale, e, n)
                yield f"crescent o={e} n={n} x{scale:g}", crescent(scale, e, n)
        yield f"wedge x{scale:g}", wedge(scale, 0.05)


def main():
    print("Thin overlaps with a closed-form depth (faceted geometry): relative error of the")
    print("reported depth (negative = too low), and the new upper bound's gap (500 boxes).")
    print(
        f"{'case':32s} {'tri':>5s} {'simple':>10s} {'meshcheck':>10s} {'gap':>9s} "
        f"{'simple ms':>9s} {'mc ms':>8s}"
    )
    errors_before, errors_after, t_before, t_after, certified = [], [], [], [], 0
    rows = list(thin_cases())
    for label, (a, b, want) in rows:
        v, f = solid_of(a, b)
        old = simple_depth(v, f)
        new = depth_bounds(v, f, max_boxes=500)
        certified += new.is_certified
        eb, ea = (old - want) / want, (new.lower - want) / want
        errors_before.append(eb)
        errors_after.append(ea)
        tb = best_ms(lambda v=v, f=f: simple_depth(v, f), 3)
        ta = best_ms(lambda v=v, f=f, t=1e-5 * want: depth_bounds(v, f, decide_at=t), 3)
        t_before.append(tb)
        t_after.append(ta)
        gap = new.upper / new.lower - 1.0
        print(f"{label:32s} {len(f):5d} {eb:10.2e} {ea:10.2e} {gap:9.1e} {tb:9.1f} {ta:8.1f}")
    eb, ea = np.abs(errors_before), np.abs(errors_after)
    print(
        f"\n{len(rows)} cases. |error| worst / median: simple {eb.max():.2e} / "
        f"{np.median(eb):.2e}, meshcheck {ea.max():.2e} / {np.median(ea):.2e}"
    )
    print(f"upper bound within 1e-3 of the ball (certified): {certified} of {len(rows)}")
    print(
        f"depth time, median over the cases: simple {np.median(t_before):.1f} ms, meshcheck "
        f"{np.median(t_after):.1f} ms (ratio {np.median(np.divide(t_after, t_before)):.2f})"
    )

    print("\nThe verify bench's pairs (bench/verify.py): depth and whole verify_pair time")
    pairs = [
        (
            "pin 3.2 in hole 3.0, 32 facets",
            prism_tube(3.0, 10.0, 0.0, 10.0, 32),
            pin(3.2, -4.0, 14.0, 32),
        )
    ]
    bodies = load_bodies([f"sample_meshes/{n}" for n in ("plate.stl", "bolt_m8_oversized.stl")])
    pairs.append(("sample: plate x bolt_m8_oversized", bodies[0].world, bodies[1].world))
    print(
        f"{'pair':36s} {'simple':>9s} {'meshcheck':>9s} {'depth ms simple':>15s} "
        f"{'meshcheck':>6s} {'verify_pair ms':>14s}"
    )
    for label, a, b in pairs:
        v, f = solid_of(a, b)
        tol = 1e-3
        old, new = simple_depth(v, f), depth_bounds(v, f, decide_at=tol)
        tb = best_ms(lambda v=v, f=f: simple_depth(v, f))
        ta = best_ms(lambda v=v, f=f, t=tol: depth_bounds(v, f, decide_at=t))
        tv = best_ms(lambda a=a, b=b, t=tol: verify_pair(a, b, tolerance=t, clearance=None))
        print(f"{label:36s} {old:9.6f} {new.lower:9.6f} {tb:15.1f} {ta:6.1f} {tv:14.1f}")
    print("(verify_pair with the simple estimate = verify_pair - depth + simple depth)")

    print("\nSlivers 0.3 tolerance thick (tolerance 1e-3): touching, decided on proof; time of the")
    print("depth step (simple: a ball found under the tolerance, which proves nothing)")
    slivers = [
        ("flat: tilted boxes", tilted_slab_pair(1.0, 3e-4)),
        ("curved: pin in hole, 32 facets", annulus(1.0, 3e-4, 32)),
        ("curved: pin in hole, 128 facets", annulus(1.0, 3e-4, 128)),
        ("curved: crescent, 32 facets", crescent(1.0, 3e-4, 32)),
    ]
    print(
        f"{'sliver':36s} {'simple':>8s} {'meshcheck':>9s} {'upper':>9s} {'ms simple':>9s} "
        f"{'mc ms':>7s}"
    )
    for label, (a, b, _) in slivers:
        v, f = solid_of(a, b)
        tol = 1e-3
        old, new = simple_depth(v, f), depth_bounds(v, f, decide_at=tol)
        tb = best_ms(lambda v=v, f=f: simple_depth(v, f), 1)
        ta = best_ms(lambda v=v, f=f, t=tol: depth_bounds(v, f, decide_at=t), 1)
        verdict = "touch" if new.upper <= tol else "interf"
        simple = "touch" if old <= tol else "interf"
        print(f"{label:36s} {simple:>8s} {verdict:>9s} {new.upper:9.2e} {tb:9.1f} {ta:7.1f}")


if __name__ == "__main__":
    main()
