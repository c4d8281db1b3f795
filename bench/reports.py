"""Rendering reports: every format for 10,000 findings, against ``json.dumps`` of the findings.

Run from the repository root::

    python bench/reports.py            # 10,000 findings
    python bench/reports.py --n 1000

The peer, measured in the same process, is ``json.dumps([f.to_dict() for f in findings])``: the
least any report has to do. A ratio is ``format time / peer time``; every format renders every
name through ``printable`` and a tenth of the names hold control characters.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from meshcheck.outcome import CheckResult
from meshcheck.reports import FORMATS, render
from meshcheck.results import Finding, Location, PairVerdict, Part, Verdict, finding_id
from meshcheck.settings import Settings


def make(n: int) -> CheckResult:
    findings, names = [], set()
    statuses = ("interference", "touching", "clearance")
    for k in range(n):
        a = f"assembly/station_{k % 37}/part_{k:05d}.stl"
        b = f"assembly/frame_{k % 11}{chr(10) if k % 10 == 0 else ''}.stl"
        a, b = sorted((a, b))
        status = statuses[k % 3]
        findings.append(
            Finding(
                a,
                b,
                PairVerdict(
                    Verdict(status),
                    0.0 if status != "clearance" else 0.3,
                    depth=0.2 if status == "interference" else None,
                    volume=1.5 if status == "interference" else None,
                    location=Location(np.array([k * 1e-3, 40.0, 5.0]), np.zeros(3), np.ones(3)),
                ),
                id=finding_id(a, "x", b, "y"),
                tolerance=1e-4,
            )
        )
        names.update((a, b))
    parts = [Part(name, name, 100, True, 1) for name in sorted(names)]
    return CheckResult(findings, parts, Settings.from_options(clearance=0.5))


def best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10_000)
    args = parser.parse_args()
    result = make(args.n)
    peer = best(lambda: json.dumps([f.to_dict() for f in result.findings]))
    print(f"{args.n} findings; peer json.dumps of the findings: {peer * 1e3:.1f} ms")
    print(f"{'format':10} {'ms':>8} {'/ peer':>8}")
    for fmt in FORMATS:
        if fmt == "html":
            continue
        t = best(lambda fmt=fmt: render(result, fmt))
        print(f"{fmt:10} {t * 1e3:8.1f} {t / peer:8.1f}x")


if __name__ == "__main__":
    main()
