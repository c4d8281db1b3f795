"""Where loading files in worker processes starts to pay: serial against a fresh pool.

Run from the repository root::

    python bench/load_parallel.py                      # 500..10,000 binary STL files, 2 jobs
    python bench/load_parallel.py --format obj         # the same parts as OBJ (text) files
    python bench/load_parallel.py --sizes 2000 --jobs 4

The files are bench/assemblies.py's grid, one part per file (binary STL ~23 kB each, as CAD
exports them; ``--format obj`` rewrites them as OBJ). For the first N files the script times,
in one process and alternating (best of ``--repeat``):

- ``serial``: ``load_bodies`` here, one file after another;
- ``pool``: the same through a ``LocalPool(jobs)`` started for the call, so the time includes
  starting the workers (their imports): what a run pays when no later stage uses the workers
  (an unchanged re-run whose pair verdicts are all cached);
- ``warm pool``: through workers already started (a run whose later stages start them anyway).

With ``--compare-with CHECKOUT`` (a source tree of another meshcheck version, its kernels built
with ``python setup.py build_ext --inplace``) it also times that version's serial loading of the
same files in a subprocess, alternating with this one's::

    git archive OLD_COMMIT | tar -x -C /tmp/old && (cd /tmp/old && python setup.py build_ext -i)
    python bench/load_parallel.py --sizes 2000 --compare-with /tmp/old

(To time the old version without xxhash, as its own environment had it, put an ``xxhash.py``
that raises ImportError into CHECKOUT.)

It prints the ratios pool / serial, and what ``load.files.parallel_pays`` decides for each size
(its constants should make it say yes where the fresh pool's ratio is below 1). Both give
identical bodies (names, digests, placements; checked).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from assemblies import write_assembly  # noqa: E402


def load(paths, executor=None):
    from meshcheck.load import load_bodies

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        bodies = load_bodies(paths, executor=executor, parallel=executor is not None)
        return time.perf_counter() - start, bodies


_OTHER = """
import sys, time, warnings
from meshcheck.load import load_bodies
paths = sys.argv[1:]
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    load_bodies(paths[:10])
    start = time.perf_counter()
    load_bodies(paths)
print(time.perf_counter() - start)
"""


def other_serial(checkout: str, paths: list[str]) -> float:
    """Serial loading time of the meshcheck in ``checkout``, in a fresh process."""
    import subprocess

    root = os.path.abspath(checkout)  # also the working directory: -c puts it first on the path
    out = subprocess.run(
        [sys.executable, "-c", _OTHER, *paths],
        env=dict(os.environ, PYTHONPATH=root),
        cwd=root,
        capture_output=True,
        text=True,
        check=True,
    )
    return float(out.stdout.split()[-1])


def same(a, b) -> bool:
    return len(a) == len(b) and all(
        x.name == y.name
        and x.digest == y.digest
        and x.transform.tobytes() == y.transform.tobytes()
        and x.is_closed == y.is_closed
        for x, y in zip(a, b, strict=True)
    )


def main(argv=None) -> None:
    from meshcheck.execute import LocalPool, Task
    from meshcheck.load import files

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[500, 2000, 5000, 10000])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=2, help="best of this many runs")
    parser.add_argument("--format", choices=["stl", "obj"], default="stl")
    parser.add_argument("--compare-with", metavar="CHECKOUT", help="another meshcheck's tree")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        paths, _ = write_assembly(max(args.sizes), tmp)
        if args.format == "obj":
            import trimesh

            for k, path in enumerate(paths):
                obj = path[:-4] + ".obj"
                trimesh.load_mesh(path).export(obj)
                os.remove(path)
                paths[k] = obj
        load(paths[:10])  # this process's imports, once
        print(f"{args.format.upper()} files, {args.jobs} jobs")
        other = f" {'other ms/file':>14} {'other/serial':>13}" if args.compare_with else ""
        print(
            f"{'files':>6} {'MiB':>6} {'serial s':>9} {'ms/file':>8} {'pool s':>7} "
            f"{'pool/serial':>12} {'warm s':>7} {'warm/serial':>12} {'pays?':>6}{other}"
        )
        for n in args.sizes:
            chosen = paths[:n]
            mib = sum(os.path.getsize(p) for p in chosen) / (1 << 20)
            serial = fresh = warm = before = np.inf
            for _ in range(args.repeat):
                if args.compare_with:
                    before = min(before, other_serial(args.compare_with, chosen))
                seconds, expected = load(chosen)
                serial = min(serial, seconds)
                with LocalPool(args.jobs) as pool:
                    seconds, bodies = load(chosen, pool)
                    fresh = min(fresh, seconds)
                    assert same(expected, bodies), "parallel bodies differ from serial ones"
                with LocalPool(args.jobs) as pool:
                    pool.map("meshcheck.execute:echo", [Task((k,)) for k in range(args.jobs)])
                    warm = min(warm, load(chosen, pool)[0])
            compared = f" {1e3 * before / n:14.3f} {before / serial:13.2f}" if other else ""
            print(
                f"{n:6d} {mib:6.0f} {serial:9.2f} {1e3 * serial / n:8.3f} {fresh:7.2f} "
                f"{fresh / serial:12.2f} {warm:7.2f} {warm / serial:12.2f} "
                f"{'yes' if files.parallel_pays(chosen, args.jobs) else 'no':>6}{compared}"
            )


if __name__ == "__main__":
    main()
