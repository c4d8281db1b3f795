"""The kernels built on the stable ABI (abi3, the wheels' build) against the per-version build.

Command::

    python bench/abi3.py

(options: ``--runs N`` runs of each build, alternating; ``--rounds R`` and ``--pairs P`` are
passed to ``bench/gjk.py``).

Builds ``meshcheck.geometry._kernels`` twice from this checkout with ``setup.py build_ext``: once
as the wheels build it (``Py_LIMITED_API``, one ``.abi3`` module for every Python from 3.11) and
once per Python version (``MESHCHECK_LIMITED_API=0``). Each build goes into its own copy of the
package, and ``bench/gjk.py`` runs against each copy in turn, alternating, so both meet the same
machine load. Each gjk run measures its contenders against python-fcl in the same process; this
script prints, per contender, the median over runs of that ``fcl / this`` ratio (CPU time) for
each build, and the abi3 build's speed relative to the per-version build (1.00x: the same).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROW = re.compile(r"^(\s*\S.*?)\s+([\d.]+)\s+([\d.]+)x\s+([\d.]+)\s+([\d.]+)x$")


def build(limited: bool, into: Path) -> Path:
    """Copy the package into ``into`` and build the kernels there; returns the module's path."""
    shutil.copytree(
        ROOT / "meshcheck",
        into / "meshcheck",
        ignore=shutil.ignore_patterns("*.so", "*.pyd", "__pycache__"),
    )
    shutil.copytree(ROOT / "bench", into / "bench")
    env = {**os.environ, "MESHCHECK_LIMITED_API": "1" if limited else "0"}
    subprocess.run(
        [
            sys.executable,
            "setup.py",
            "-q",
            "build_ext",
            "--build-lib",
            str(into),
            "--build-temp",
            str(into / "build"),
        ],
        cwd=ROOT,
        env=env,
        check=True,
        capture_output=True,
    )
    (module,) = (into / "meshcheck" / "geometry").glob("_kernels.*")
    return module


def run_gjk(where: Path, gjk_args: list[str]) -> dict[str, float]:
    """One run of bench/gjk.py on the copy at ``where``: contender -> fcl / this (CPU)."""
    out = subprocess.run(
        [sys.executable, str(where / "bench" / "gjk.py"), *gjk_args],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return {m[1].strip(): float(m[5]) for line in out.splitlines() if (m := ROW.match(line))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--pairs", type=int, default=2000)
    args = parser.parse_args()
    gjk_args = ["--rounds", str(args.rounds), "--pairs", str(args.pairs)]
    with tempfile.TemporaryDirectory() as tmp:
        builds = {"abi3": Path(tmp, "abi3"), "per-version": Path(tmp, "per-version")}
        for name, where in builds.items():
            print(f"{name}: {build(name == 'abi3', where).name}")
        ratios: dict[str, dict[str, list[float]]] = {name: {} for name in builds}
        for _ in range(args.runs):
            for name, where in builds.items():
                for contender, ratio in run_gjk(where, gjk_args).items():
                    ratios[name].setdefault(contender, []).append(ratio)
    print(
        f"\n{args.runs} alternating runs of bench/gjk.py {' '.join(gjk_args)}; "
        "medians of fcl / this (CPU time, higher is faster)"
    )
    print(f"{'contender':<34}{'abi3':>10}{'per-version':>13}{'abi3 speed':>12}")
    for contender, per_version in ratios["per-version"].items():
        a, p = statistics.median(ratios["abi3"][contender]), statistics.median(per_version)
        print(f"{contender:<34}{a:>9.2f}x{p:>12.2f}x{a / p:>11.2f}x")


if __name__ == "__main__":
    main()
