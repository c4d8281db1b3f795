"""Measure CoACD settings: decomposition time against how well the pieces filter part pairs.

Run from the repository root::

    python bench/coacd_settings.py            # the fast settings, about 3 minutes on 2 cores
    python bench/coacd_settings.py --slow     # also CoACD's defaults and others (an hour)
    python bench/coacd_settings.py --quick    # three settings
    python bench/coacd_settings.py --settings "t0.2 r300 mcts(5,20,1)" --parts gear_48

The verify stage decides every candidate on the real meshes, so the convex pieces only have to be
a good filter: few piece pairs within reach of a neighbour's pieces, and few part pairs left for
the exact verify stage. For each CoACD setting this script decomposes a set of CAD-like parts
(generated here with manifold3d: plates with many holes, brackets with slots, a housing with
pockets, a gear; 3,000 to 10,000 triangles), applies meshcheck's triangle-cover fix-up, and places
every part in a small test rig next to pins and blocks that come close without touching. It reports
the cold decomposition time per part, the number of pieces, and how many rig pairs the pieces
cannot clear (lower is better; the part's hull alone clears none of them).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import trimesh

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one thread per decomposition, as the workers run
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

SEGMENTS = 32


# --------------------------------------------------------------------------------------------
# CAD-like parts (millimetres), built with manifold3d booleans.


def _m():
    import manifold3d

    return manifold3d


def _cyl(radius, z0, z1, x=0.0, y=0.0, segments=SEGMENTS):
    m = _m()
    return m.Manifold.cylinder(z1 - z0, radius, radius, segments).translate((x, y, z0))


def _box(lower, upper):
    m = _m()
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    return m.Manifold.cube(tuple(upper - lower)).translate(tuple(lower))


def _slot(x0, y0, x1, y1, radius, z0, z1, segments=SEGMENTS):
    m = _m()
    ends = [_cyl(radius, z0, z1, x0, y0, segments), _cyl(radius, z0, z1, x1, y1, segments)]
    return m.Manifold.batch_hull(ends)


def _trimesh(manifold) -> trimesh.Trimesh:
    mesh = manifold.to_mesh()
    return trimesh.Trimesh(
        np.asarray(mesh.vert_properties[:, :3], dtype=np.float64),
        np.asarray(mesh.tri_verts, dtype=np.int64),
        process=True,
    )


def perforated_plate(nx: int = 8, ny: int = 5, pitch: float = 20.0, radius: float = 3.3):
    """A plate with an ``nx`` x ``ny`` grid of through holes, corner at the origin."""
    body = _box([0, 0, 0], [nx * pitch, ny * pitch, 8])
    holes = [
        _cyl(radius, -1, 9, (i + 0.5) * pitch, (j + 0.5) * pitch)
        for i in range(nx)
        for j in range(ny)
    ]
    return _trimesh(body - _m().Manifold.batch_boolean(holes, _m().OpType.Add))


def slotted_bracket(segments: int = 96):
    """An L-bracket with slots in the base and holes in the upright."""
    m = _m()
    base = _box([0, 0, 0], [120, 60, 8])
    upright = _box([0, 0, 8], [8, 60, 80])
    rib = m.Manifold.batch_hull([_box([8, 28, 8], [60, 32, 9]), _box([8, 28, 8], [9, 32, 70])])
    body = base + upright + rib
    cuts = [_slot(25 + 30 * i, 12, 25 + 30 * i, 22, 3.5, -1, 9, segments) for i in range(3)]
    cuts += [_slot(25 + 30 * i, 38, 25 + 30 * i, 48, 3.5, -1, 9, segments) for i in range(3)]
    for k in range(3):
        hole = _cyl(4.0, -1, 10, 20 + 20 * k, 0, segments).rotate((0, -90, 0)).translate((9, 0, 0))
        cuts += [hole.translate((0, 12, 0)), hole.translate((0, 48, 0))]
    return _trimesh(body - m.Manifold.batch_boolean(cuts, m.OpType.Add))


def pocketed_housing(segments: int = 96):
    """An open box housing with side pockets, bosses and bolt holes."""
    m = _m()
    outer = _box([0, 0, 0], [140, 90, 50])
    inner = _box([6, 6, 6], [134, 84, 51])
    body = outer - inner
    bosses = [_cyl(7, 6, 40, x, y, segments) for x in (16, 124) for y in (16, 74)]
    body = body + m.Manifold.batch_boolean(bosses, m.OpType.Add)
    cuts = [_cyl(2.5, 10, 41, x, y, segments) for x in (16, 124) for y in (16, 74)]
    cuts += [_box([20 + 30 * i, -1, 15], [40 + 30 * i, 3, 35]) for i in range(4)]
    cuts += [_box([20 + 30 * i, 87, 15], [40 + 30 * i, 91, 35]) for i in range(4)]
    cuts += [
        _cyl(12, -1, 7, 70, 45, segments),
        _cyl(4, -1, 7, 40, 45, segments),
        _cyl(4, -1, 7, 100, 45, segments),
    ]
    return _trimesh(body - m.Manifold.batch_boolean(cuts, m.OpType.Add))


def gear(teeth: int = 48, radius: float = 40.0, width: float = 12.0, segments: int = 96):
    """A spur gear with trapezoid teeth, a bore, a keyway and lightening holes."""
    m = _m()
    root = radius - 4.0
    angles = np.linspace(0, 2 * np.pi, teeth, endpoint=False)
    pitch = 2 * np.pi / teeth
    outline = []
    for a in angles:
        # involute-like flank: the tooth narrows from root to tip in 6 steps
        flank = [(0.3 - 0.14 * t**1.5, root + (radius - root) * t) for t in np.linspace(0, 1, 6)]
        for da, r in [(-d, r) for d, r in flank] + [(d, r) for d, r in reversed(flank)]:
            outline.append((r * np.cos(a + da * pitch), r * np.sin(a + da * pitch)))
    section = m.CrossSection([np.asarray(outline)])
    body = m.Manifold.extrude(section, width)
    hub = _cyl(12, 0, width + 8, segments=segments)
    cuts = [_cyl(6, -1, width + 9, segments=segments), _box([-2, 5, -1], [2, 8, width + 9])]
    cuts += [
        _cyl(6, -1, width + 1, 24 * np.cos(a), 24 * np.sin(a), segments)
        for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)
    ]
    return _trimesh(body + hub - m.Manifold.batch_boolean(cuts, m.OpType.Add))


PARTS = {
    "plate_40_holes": lambda: perforated_plate(8, 5),
    "plate_60_holes": lambda: perforated_plate(10, 6, pitch=16.0, radius=2.8),
    "slotted_bracket": slotted_bracket,
    "pocketed_housing": pocketed_housing,
    "gear_48": gear,
}


# --------------------------------------------------------------------------------------------
# The filter test: pins through every hole of a part and probes close to its faces.


def probes(mesh: trimesh.Trimesh, *, count: int = 200, gap: float = 0.3, seed: int = 0):
    """Small spheres just outside the surface of ``mesh``, ``gap`` mm away, none touching it.

    They sit in holes, slots and pockets as well as on outer faces: exactly where a hull that
    bulges over a hole would raise a candidate that is not there.
    """
    rng = np.random.default_rng(seed)
    points, face = trimesh.sample.sample_surface_even(mesh, count * 3, seed=seed)
    normals = mesh.face_normals[face]
    radius = 1.0
    centres = points + normals * (radius + gap)
    # Keep probes whose sphere stays clear of the part (exact distance on the real mesh).
    from meshcheck.geometry.triangles import point_distances, winding_numbers

    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    dist = point_distances(np.ascontiguousarray(centres), v, f)
    inside = winding_numbers(np.ascontiguousarray(centres), v, f) > 0.5
    keep = (dist >= radius + 0.5 * gap) & ~inside
    centres = centres[keep]
    pick = rng.choice(len(centres), size=min(count, len(centres)), replace=False)
    return centres[np.sort(pick)], radius


def surviving_probes(pieces, centres, radius, reach):
    """Probes within ``reach`` of some piece (exact convex distance by an LP-free support test)."""
    from meshcheck.geometry import pack_convex, query_pairs

    sphere = trimesh.creation.icosphere(subdivisions=1, radius=radius).vertices
    shapes = list(pieces) + [sphere + c for c in centres]
    pack = pack_convex(shapes)
    p = len(pieces)
    pairs = np.array([(i, p + k) for k in range(len(centres)) for i in range(p)], dtype=np.int64)
    res = query_pairs(pack, pairs, tolerance=1e-6, depth=False)
    near = (res.status != 0) | (res.distance <= reach)
    hit = np.zeros(len(centres), dtype=bool)
    np.logical_or.at(hit, pairs[near, 1] - p, True)
    return int(hit.sum()), int(near.sum())


def _fast(threshold, resolution, nodes, iterations, depth, **extra):
    return dict(
        threshold=threshold,
        resolution=resolution,
        mcts_nodes=nodes,
        mcts_iterations=iterations,
        mcts_max_depth=depth,
        **extra,
    )


SETTINGS = {
    # name: keyword options of coacd.run_coacd; None is the part's hull alone (no CoACD)
    "hull only": None,
    "coacd defaults t0.05": dict(threshold=0.05),
    "t0.1": dict(threshold=0.1),
    "t0.1 r1000 mcts(10,60,2)": _fast(0.1, 1000, 10, 60, 2),
    "t0.1 r500 mcts(10,40,2)": _fast(0.1, 500, 10, 40, 2),
    "t0.05 r300 mcts(5,20,1)": _fast(0.05, 300, 5, 20, 1),
    "t0.1 r300 mcts(5,20,2)": _fast(0.1, 300, 5, 20, 2),
    "t0.1 r300 mcts(5,20,1)": _fast(0.1, 300, 5, 20, 1),
    "t0.1 r200 mcts(4,10,1)": _fast(0.1, 200, 4, 10, 1),
    "t0.15 r300 mcts(5,20,1)": _fast(0.15, 300, 5, 20, 1),
    "t0.2 r500 mcts(8,30,1)": _fast(0.2, 500, 8, 30, 1),
    "t0.2 r300 mcts(5,20,1)": _fast(0.2, 300, 5, 20, 1),
    "t0.2 r300 mcts(5,20,1) ch32": _fast(0.2, 300, 5, 20, 1, max_ch_vertex=32),
    "t0.3 r300 mcts(5,20,1)": _fast(0.3, 300, 5, 20, 1),
}
QUICK = ["hull only", "t0.1 r300 mcts(5,20,1)", "t0.2 r300 mcts(5,20,1)"]
# Each of these took over 2 minutes on at least one part here (CoACD's time is erratic).
SLOW = [
    "coacd defaults t0.05",
    "t0.1",
    "t0.1 r1000 mcts(10,60,2)",
    "t0.1 r500 mcts(10,40,2)",
    "t0.05 r300 mcts(5,20,1)",
    "t0.1 r300 mcts(5,20,2)",
    "t0.1 r200 mcts(4,10,1)",
]


def main(argv=None) -> None:
    from meshcheck.decompose import cover_triangles, run_coacd

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="only a few settings")
    parser.add_argument("--slow", action="store_true", help="also the slow settings (an hour)")
    parser.add_argument("--parts", nargs="*", default=list(PARTS), help="parts to use")
    parser.add_argument("--settings", nargs="*", default=None, help="setting names to use")
    args = parser.parse_args(argv)
    names = args.settings or (
        QUICK if args.quick else [n for n in SETTINGS if args.slow or n not in SLOW]
    )

    meshes = {name: PARTS[name]() for name in args.parts}
    rigs = {name: probes(mesh) for name, mesh in meshes.items()}
    for name, mesh in meshes.items():
        print(f"# {name}: {len(mesh.faces)} triangles, {len(rigs[name][0])} probes", flush=True)
    reach = 0.3 * 0.5 + 1e-3  # half the probe gap: a good piece set clears most probes

    header = f"{'setting':32s} {'s/part':>7s} {'max s':>6s} {'pieces':>7s} {'probes':>7s}"
    print(header + "  (probes: near a piece / total, lower is better)")
    for setting in names:
        options = SETTINGS[setting]
        times, pieces_total, near_total, probe_total = [], 0, 0, 0
        per_part = []
        for name, mesh in meshes.items():
            t0 = time.perf_counter()
            pieces = run_coacd(mesh, **options) if options is not None else []
            pieces = cover_triangles(mesh.vertices, mesh.faces, pieces)
            times.append(time.perf_counter() - t0)
            centres, radius = rigs[name]
            near, _ = surviving_probes(pieces, centres, radius, reach)
            pieces_total += len(pieces)
            near_total += near
            probe_total += len(centres)
            per_part.append(f"{name}={times[-1]:.1f}s/{len(pieces)}p/{near}")
        print(
            f"{setting:32s} {np.mean(times):7.2f} {np.max(times):6.1f} {pieces_total:7d} "
            f"{near_total:4d}/{probe_total}   " + " ".join(per_part),
            flush=True,
        )


if __name__ == "__main__":
    main()
