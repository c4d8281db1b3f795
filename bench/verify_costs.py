"""Calibrate ``verify.batch``'s expected seconds: what a pair costs the exact stage, per class.

Run from the repository root, on any assembly meshcheck reads (the real ones of
``bench/real_assemblies.py`` are the reference)::

    python bench/verify_costs.py DATA/prepared/cycloidal.glb DATA/prepared/pr2_zero_joints.glb

Each file is checked in this process with ``-j 1``, an empty cache directory and a fresh key
(a cold run), and the CPU seconds of every ``verify_pair`` call are grouped by the class
``batch.expected_seconds`` gives the pair: "solid" (surfaces may meet, both meshes closed, hulls
penetrating: the shared solid and its certified depth), "near" (the triangle search alone) and
"apart" (only the buried-shell test). It prints, per file and class, the pairs, their mean and
total seconds, beside the constants ``PAIR_SECONDS`` and ``SOLID_SECONDS`` assume.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from meshcheck.cli import main as meshcheck_main  # noqa: E402
from meshcheck.verify import batch  # noqa: E402


def measure(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Expected and measured CPU seconds of each verified pair of a cold ``-j 1`` run."""
    expected: list[np.ndarray] = []
    measured: list[float] = []
    original_expected, original_verify = batch.expected_seconds, batch.verify_pair

    def expected_seconds(*args, **kwargs):
        cost = original_expected(*args, **kwargs)
        expected.append(cost)
        return cost

    def verify_pair(*args, **kwargs):
        start = time.process_time()
        verdict = original_verify(*args, **kwargs)
        measured.append(time.process_time() - start)
        return verdict

    batch.expected_seconds, batch.verify_pair = expected_seconds, verify_pair
    os.environ["MESHCHECK_CACHE_SECRET"] = os.urandom(16).hex()
    try:
        with tempfile.TemporaryDirectory() as cache:
            argv = ["-j", "1", "--cache-dir", cache, "--format", "json", "-o", os.devnull, path]
            try:
                meshcheck_main(argv, standalone_mode=False)
            except SystemExit:
                pass
    finally:
        batch.expected_seconds, batch.verify_pair = original_expected, original_verify
    cost = np.concatenate(expected) if expected else np.zeros(0)
    return cost[: len(measured)], np.asarray(measured)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    args = parser.parse_args(argv)
    print(f"PAIR_SECONDS {batch.PAIR_SECONDS}  SOLID_SECONDS {batch.SOLID_SECONDS}")
    print(f"{'file':28s} {'class':6s} {'pairs':>6s} {'mean s':>8s} {'total s':>8s}")
    for path in args.files:
        cost, seconds = measure(path)
        classes = {
            "solid": cost > batch.PAIR_SECONDS,
            "near": cost == batch.PAIR_SECONDS,
            "apart": cost < batch.PAIR_SECONDS,
        }
        for name, mask in classes.items():
            if mask.any():
                s = seconds[mask]
                print(
                    f"{os.path.basename(path)[:28]:28s} {name:6s} {len(s):6d} "
                    f"{s.mean():8.4f} {s.sum():8.2f}"
                )


if __name__ == "__main__":
    main()
