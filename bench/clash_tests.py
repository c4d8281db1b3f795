"""Clash tests: one run of several tests against one run per test, on the same assembly.

Run from the repository root::

    python bench/clash_tests.py            # 200-part assembly (bench/assemblies.py's grid)
    python bench/clash_tests.py --size 100

Three tests a CAD team might write for the grid (pins clear of their plates by 0.5 mm, brackets
on their plates, every part against every part) are checked

- ``together``: as one run with the three ``[[test]]`` tables (``Settings.tests``): loaded,
  pruned, decomposed and verified once;
- ``apart``: as three runs, one per test (its sides as ``groups``, its clearance and fail_on).

Both without a cache, in this process (``-j 1``), best of ``--repeat``; the findings of each test
are checked to be the same both ways. Prints the seconds and the ratio apart / together.
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

TESTS = [
    "pins clear:*pin*:*plate*:clearance=0.5",
    "brackets seated:*bracket*:*plate*:fail_on=interference",
    "everything:*:*",
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=200, help="parts in the assembly")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the best is kept")
    args = parser.parse_args()

    from meshcheck.config import parse_test
    from meshcheck.pipeline import check

    with tempfile.TemporaryDirectory() as folder:
        paths, _ = write_assembly(args.size, folder)
        options = {"config": None, "use_cache": False, "jobs": 1}
        tests = [parse_test(t) for t in TESTS]

        def together():
            return check(paths, tests=TESTS, **options)

        def apart():
            return [
                check(paths, groups=t.sides, clearance=t.clearance, fail_on=t.fail_on, **options)
                for t in tests
            ]

        together()  # imports and compiled kernels loaded before timing
        timed = {}
        for name, run in (("together", together), ("apart", apart)):
            best = float("inf")
            for _ in range(args.repeat):
                start = time.perf_counter()
                out = run()
                best = min(best, time.perf_counter() - start)
            timed[name] = (best, out)

    (t_together, one), (t_apart, runs) = timed["together"], timed["apart"]
    for test, alone in zip(tests, runs, strict=True):
        mine = one.for_test(test.name).findings
        assert [(f.a, f.b, f.status) for f in mine] == [
            (f.a, f.b, f.status) for f in alone.findings
        ]
    print(f"{len(paths)} parts, {len(tests)} tests, {len(one.findings)} findings")
    print(f"together (one run of {len(tests)} tests): {t_together:.2f} s")
    print(f"apart ({len(tests)} runs of one test):    {t_apart:.2f} s")
    print(f"apart / together: {t_apart / t_together:.2f}")


if __name__ == "__main__":
    main()
