"""Where verifying pairs in worker processes starts to pay: serial against a fresh 2-process pool.

Run from the repository root::

    python bench/verify_parallel.py            # 400-part assembly, 25..all candidate pairs

The assembly is bench/assemblies.py's grid. The script runs the pipeline's stages up to the verify
stage once, then, for the first N pairs of the verify stage, times

- ``serial``: ``verify.batch._verify`` in this process (kernels already loaded here);
- ``pool``: the same through a ``LocalPool(2)`` started for the call, so the time includes
  starting the workers (their imports and compiled-kernel loads) and sending the meshes: what a
  warm run pays when decomposition did not start the workers.

and prints the ratio pool / serial; pairs are verified one per class (``verify.classes``), so
the counts are classes. ``batch.POOL_SECONDS`` should sit where it drops below 1. Both give
identical verdicts (checked).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from assemblies import write_assembly  # noqa: E402


def verify_stage_input(paths: list[str], cache_dir: str):
    """Bodies, and the pair classes (with their surfaces flags) the verify stage would get."""
    import dataclasses

    import numpy as np

    from meshcheck import pipeline
    from meshcheck.geometry import query_pairs
    from meshcheck.load import load_bodies, local_geometries
    from meshcheck.settings import Settings
    from meshcheck.tolerances import pair_tolerances, part_sizes
    from meshcheck.verify.classes import pair_classes

    settings = Settings(cache_dir=cache_dir)
    bodies = load_bodies(paths)
    geometry = local_geometries(bodies)
    names = [pipeline._names(b) for b in bodies]
    hulls = pipeline._world_hulls(bodies, geometry)
    diagonal, magnitude = part_sizes(hulls.lower, hulls.upper, [b.is_float32 for b in bodies])
    deflection = np.array([b.deflection for b in bodies])
    pairs = pipeline.select_pairs(hulls, settings, names, diagonal, magnitude, deflection)
    tolerance = pair_tolerances(diagonal, magnitude, pairs, deflection=deflection)
    query = query_pairs(hulls, pairs, tolerance=tolerance, depth=False, max_distance=tolerance)
    near = pipeline.may_come_within(query, tolerance)
    classes = pair_classes(bodies, pairs[near], tolerance[near], geometry=geometry)
    packs, _ = pipeline.decompose_parts(bodies, classes, settings, geometry=geometry)
    apart = ~pipeline.surfaces_near(packs, classes, None)
    return bodies, dataclasses.replace(classes, surfaces_apart=apart)


def main(argv=None) -> None:
    import numpy as np

    from meshcheck.execute import LocalPool
    from meshcheck.verify import batch

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=400)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        paths, _ = write_assembly(args.size, tmp)
        bodies, classes = verify_stage_input(paths, os.path.join(tmp, "c"))
        every = np.arange(len(classes))
        # warm this process's kernels and memo-free caches once
        batch._verify(bodies, classes, every[:5], None, None, _ignore)
        print(f"{len(classes)} pair classes in the verify stage of a {args.size}-part assembly")
        print(f"{'classes':>7} {'serial s':>9} {'pool(2) s':>10} {'pool/serial':>12}")
        sizes = [n for n in (25, 50, 100, 200, 400, 800, 1600) if n < len(classes)]
        for n in [*sizes, len(classes)]:
            todo = every[:n]
            start = time.perf_counter()
            serial = batch._verify(bodies, classes, todo, None, None, _ignore)
            t_serial = time.perf_counter() - start
            start = time.perf_counter()
            with LocalPool(2) as pool:
                parallel = batch._verify(bodies, classes, todo, None, _Forced(pool), _ignore)
            t_pool = time.perf_counter() - start
            assert [v.status for v in serial] == [v.status for v in parallel]
            assert [v.distance for v in serial] == [v.distance for v in parallel]
            print(f"{n:7d} {t_serial:9.2f} {t_pool:10.2f} {t_pool / t_serial:12.2f}")


def _ignore(done: int) -> None:
    """A progress callback that shows nothing."""


class _Forced:
    """A pool that claims to be distributed, so ``_verify`` uses it at any size."""

    is_distributed = True

    def __init__(self, pool):
        self.pool, self.jobs = pool, pool.jobs

    def map(self, *args, **kwargs):
        return self.pool.map(*args, **kwargs)


if __name__ == "__main__":
    main()
