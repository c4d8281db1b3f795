"""Verify-stage speed: verify_pair vs python-fcl's mesh distance on the same pairs, same run.

Run from the repository root: python bench/verify.py
Both sides start from the meshes (fcl builds its BVHs each call, as verify_pair does).
"""

from __future__ import annotations

import time

import fcl
import numpy as np
import trimesh

from meshcheck.load import load_bodies
from meshcheck.verify import verify_pair


def cylinder(r, z0, z1, n):
    c = trimesh.creation.cylinder(radius=r, height=z1 - z0, sections=n)
    return c.apply_translation([0, 0, 0.5 * (z0 + z1)])


def fcl_distance(a, b):
    def obj(m):
        model = fcl.BVHModel()
        model.beginModel(len(m.vertices), len(m.faces))
        model.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int32))
        model.endModel()
        return fcl.CollisionObject(model, fcl.Transform())

    return fcl.distance(obj(a), obj(b), fcl.DistanceRequest(), fcl.DistanceResult())


def median_ms(fn, repeat=15):
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1e3 * float(np.median(times))


def main():
    pairs = []
    for n in (32, 256):
        plate = trimesh.boolean.difference(
            [
                trimesh.creation.box(extents=[20, 20, 10]).apply_translation([0, 0, 5]),
                cylinder(3.1, -1, 11, n),
            ],
            engine="manifold",
        )
        free = trimesh.boolean.union(
            [cylinder(3.0, -4, 11, n), cylinder(5, 11, 14, n)], engine="manifold"
        )
        resting = trimesh.boolean.union(
            [cylinder(3.0, -4, 10.5, n), cylinder(5, 10, 14, n)], engine="manifold"
        )
        tris = len(plate.faces) + len(free.faces)
        pairs.append((f"bolt, 0.1 radial gap, in plate hole ({tris} tri)", plate, free, 0.1))
        pairs.append((f"bolt head resting on plate ({tris} tri)", plate, resting, 0.1))
    bodies = load_bodies(
        [
            f"sample_meshes/{f}"
            for f in (
                "plate.stl",
                "bolt_m6_a.stl",
                "bolt_m6_b.stl",
                "bolt_m6_c.stl",
                "bolt_m8_oversized.stl",
                "bracket.stl",
            )
        ]
    )
    for b in bodies[1:]:
        pairs.append((f"sample: plate x {b.name.split('/')[-1]}", bodies[0].world, b.world, 0.5))
    print(f"{'pair':55s} {'verdict':12s} {'verify ms':>9s} {'fcl ms':>8s} {'ratio':>6s}")
    for label, a, b, clearance in pairs:
        v = verify_pair(a, b, tolerance=1e-3, clearance=clearance)
        tv = median_ms(lambda a=a, b=b, c=clearance: verify_pair(a, b, tolerance=1e-3, clearance=c))
        tf = median_ms(lambda a=a, b=b: fcl_distance(a, b))
        print(f"{label:55s} {v.status:12s} {tv:9.2f} {tf:8.2f} {tv / tf:6.2f}")


if __name__ == "__main__":
    main()
