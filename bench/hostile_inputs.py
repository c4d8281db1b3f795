"""Hostile inputs: exit status, stderr lines, wall time and peak RSS of each case.

Runs ``python -m meshcheck CASE --no-cache`` in a fresh process per case (the cases of
``tests/test_hostile_inputs.py``, ``CASES``) and prints one row each. The peer is a run on a plain
two-box STL pair measured the same way: the ratios say what each hostile case costs beyond
starting the program and loading a trivial assembly.

    python bench/hostile_inputs.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_hostile_inputs import CASES, box, measured  # noqa: E402


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        peer_dir = tmp / "peer"
        peer_dir.mkdir()
        a, b = peer_dir / "a.stl", peer_dir / "b.stl"
        box().export(str(a))
        box(at=(3, 0, 0)).export(str(b))
        _, _, peer_s, peer_mb = measured([a, b], peer_dir)
        print(f"peer (two apart boxes): {peer_s:.2f} s, {peer_mb:.0f} MiB peak RSS")
        print(f"{'case':42} {'exit':>4} {'want':>4} {'stderr':>6} {'time':>12} {'peak RSS':>14}")
        for k, (name, (make, want)) in enumerate(CASES.items()):
            folder = tmp / f"case{k}"
            folder.mkdir()
            try:
                args = make(folder)
            except OSError as exc:
                print(f"{name:42} skipped: {exc}")
                continue
            status, lines, seconds, peak = measured(args, folder)
            print(
                f"{name:42} {status:>4} {int(want):>4} {len(lines):>6} "
                f"{seconds:5.2f} s {seconds / peer_s:4.2f}x {peak:6.0f} MiB {peak / peer_mb:4.2f}x"
            )


if __name__ == "__main__":
    main()
