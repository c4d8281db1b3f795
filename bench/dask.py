"""A cold check on a Dask LocalCluster against local worker processes (-j 2) on the same cores.

Run from the repository root (needs ``pip install ".[dask]"``)::

    python bench/dask.py                 # 2,000 parts
    python bench/dask.py --size 500

In one process, on bench/assemblies.py's assembly with empty caches each time:

- ``local -j 2``: ``meshcheck.check`` with two local worker processes;
- ``dask``: the same with ``scheduler=`` a ``LocalCluster`` of two single-threaded process
  workers started beforehand (its start-up is printed apart, not counted: a cluster is already
  running when users pass ``--scheduler``).

It prints both wall times and their ratio (the cost of going through Dask where it cannot win),
the tasks submitted and the bytes of meshes scattered, per part (what grows with the assembly when
more machines are added), and checks that both reports are identical.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
# This file is named dask.py: Dask must be imported before bench/ goes on the path.
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != HERE]
import distributed  # noqa: E402, F401

sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from assemblies import write_assembly  # noqa: E402


def main(argv=None) -> None:
    from distributed import LocalCluster

    from meshcheck import execute, pipeline
    from meshcheck.reports import render

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2000)
    args = parser.parse_args(argv)

    used = []
    original = pipeline.executor_for

    def recording(**kwargs):
        executor = original(**kwargs)
        used.append(executor)
        return executor

    pipeline.executor_for = recording
    os.environ.setdefault("MESHCHECK_CACHE_SECRET", "bench-dask")
    with tempfile.TemporaryDirectory() as tmp:
        os.makedirs(os.path.join(tmp, "parts"))
        paths, _ = write_assembly(args.size, os.path.join(tmp, "parts"))
        start = time.perf_counter()
        local = pipeline.check(paths, config=None, cache_dir=os.path.join(tmp, "a"), jobs=2)
        t_local = time.perf_counter() - start

        start = time.perf_counter()
        cluster = LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            env={"OMP_NUM_THREADS": "1"},
        )
        t_cluster = time.perf_counter() - start
        try:
            start = time.perf_counter()
            settings = pipeline.Settings.from_options(
                config=None, cache_dir=os.path.join(tmp, "b"), scheduler=cluster.scheduler_address
            )
            remote = pipeline.check(paths, settings)
            t_dask = time.perf_counter() - start
        finally:
            cluster.close(timeout=30)
    dask_executor = next(e for e in used if isinstance(e, execute.DaskExecutor))
    parts = len(local.parts)
    print(f"{parts} parts, cold (empty caches), 2 processes either way")
    print(f"  local -j 2          {t_local:8.2f} s")
    print(f"  dask LocalCluster   {t_dask:8.2f} s   (cluster start-up {t_cluster:.2f} s, apart)")
    print(f"  dask / local        {t_dask / t_local:8.2f}x")
    tasks = dask_executor.task_count
    print(f"  tasks submitted     {tasks} ({tasks / parts:.3f} per part)")
    print(
        f"  meshes scattered    {dask_executor.sent_bytes / 1e6:.1f} MB "
        f"({dask_executor.sent_bytes / parts / 1e3:.1f} kB per part)"
    )
    same = render(local, "json") == render(remote, "json")
    print(f"  reports identical   {same}")
    if not same:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
