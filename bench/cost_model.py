"""Calibrate ``decompose.CostModel``: what CoACD costs a part, what its pieces save the exact stage.

Run from the repository root::

    python bench/cost_model.py              # bench/coacd_settings.py's five CAD-like parts
    python bench/cost_model.py --probes 50  # fewer probe pairs per part (quicker)

For each part (3,000 to 10,000 triangles: plates with many holes, a slotted bracket, a pocketed
housing, a gear), one core:

- CoACD: ``decompose.decompose_mesh`` with meshcheck's settings (CoACD and the triangle cover), the
  time the cost model's ``coacd_seconds`` must expect;
- verify: pairs of the part with small spheres just off its surface (``coacd_settings.probes``),
  whose hulls meet: ``verify_pair`` as when the surfaces may be near, and as when the pieces proved
  them apart (only the buried-shell test is left). The difference is what the pieces save on a pair
  they clear: ``verify_seconds``;
- filter share: of the probes the part's hull reaches, the share its pieces clear.

It prints each part's figures, the least-squares lines ``a + b * triangles`` through them, and the
constants ``decompose.COST_MODEL`` holds, for comparison.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import trimesh

os.environ.setdefault("OMP_NUM_THREADS", "1")
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from coacd_settings import PARTS, probes, surviving_probes  # noqa: E402


def verify_saving(mesh: trimesh.Trimesh, centres: np.ndarray, radius: float) -> tuple[float, int]:
    """Mean seconds a probe pair's triangle search costs beyond its shell test, and the pair's
    triangles (part + probe)."""
    from meshcheck.verify.pair import verify_pair

    sphere = trimesh.creation.icosphere(subdivisions=1, radius=radius)
    memo: dict = {}
    full = apart = 0.0
    for centre in centres:
        probe = sphere.copy().apply_translation(centre)
        tol = 1e-5 * float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
        t0 = time.perf_counter()
        verify_pair(mesh, probe, tolerance=tol, clearance=None, memo=memo)
        t1 = time.perf_counter()
        verify_pair(mesh, probe, tolerance=tol, clearance=None, surfaces_apart=True, memo=memo)
        t2 = time.perf_counter()
        full, apart = full + (t1 - t0), apart + (t2 - t1)
    return (full - apart) / len(centres), len(mesh.faces) + len(sphere.faces)


def fit(x, y) -> tuple[float, float]:
    """Least-squares ``a + b * x`` through the points."""
    b, a = np.polyfit(np.asarray(x, float), np.asarray(y, float), 1)
    return float(a), float(b)


def main(argv=None) -> None:
    from meshcheck.decompose import COST_MODEL, _hull_vertices, coacd_options, decompose_mesh

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--probes", type=int, default=100)
    args = parser.parse_args(argv)
    rows = []
    print(f"{'part':18s} {'triangles':>9s} {'CoACD s':>8s} {'saving ms/pair':>14s} {'share':>6s}")
    for name, make in PARTS.items():
        mesh = make()
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)
        t0 = time.perf_counter()
        pieces = decompose_mesh(v, f, coacd_options())
        coacd = time.perf_counter() - t0
        centres, radius = probes(mesh, count=args.probes)
        reach = 0.3 * 0.5
        hull_near, _ = surviving_probes([_hull_vertices(v)], centres, radius, reach)
        piece_near, _ = surviving_probes(pieces, centres, radius, reach)
        share = (hull_near - piece_near) / max(hull_near, 1)
        saving, triangles = verify_saving(mesh, centres, radius)
        rows.append((len(f), coacd, triangles, saving, share))
        print(f"{name:18s} {len(f):9d} {coacd:8.2f} {1e3 * saving:14.2f} {share:6.2f}", flush=True)
    n, coacd, pair_n, saving, share = (np.array(c) for c in zip(*rows, strict=True))
    ca, cb = fit(n, coacd)
    va, vb = fit(pair_n, saving)
    print(f"fit: coacd_seconds  = {ca:.3g} + {cb:.3g} * triangles")
    print(f"fit: verify_seconds = {va:.3g} + {vb:.3g} * (triangles_a + triangles_b)")
    print(f"filter share: mean {share.mean():.2f}, max {share.max():.2f}")
    print(f"COST_MODEL: {COST_MODEL}")


if __name__ == "__main__":
    main()
