"""A 300-part sample: 50 copies of ``sample_meshes`` in a grid, checked once.

Run from the repository root::

    python bench/triage_300.py             # 50 copies, an 80-column table
    python bench/triage_300.py --copies 10 --width 60

Each copy goes to its own nested folder (``assembly/row_R/station_C/*.stl``), so the part names
differ only in the middle, where a plain middle cut would make them equal. It prints the first
rows of the text report as an 80-column terminal shows them, and checks what triage needs:
every interference is listed before any touching row, every line fits the width, no two
different part names were cut to the same text, and the copies' interferences (each oversized
bolt in its own plate: copies of two parts at one relative placement) are one pattern group.
The peer, measured in the same run, is the check itself: the ratio is the report's rendering
time over the check's (the ordering, shortening and grouping must cost nothing next to the
geometry).
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import sys
import tempfile
import time

import numpy as np
import trimesh

from meshcheck.pipeline import check
from meshcheck.reports import View, render
from meshcheck.results import clash_groups

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def build(where: str, copies: int) -> list[str]:
    """Write ``copies`` copies of the sample, each moved to its grid cell; their paths."""
    meshes = {
        os.path.basename(p): trimesh.load(p, force="mesh")
        for p in sorted(glob.glob(os.path.join(ROOT, "sample_meshes", "*.stl")))
    }
    lower = np.min([m.bounds[0] for m in meshes.values()], axis=0)
    upper = np.max([m.bounds[1] for m in meshes.values()], axis=0)
    step = 1.5 * float(max(upper[0] - lower[0], upper[1] - lower[1]))
    side = max(int(copies**0.5), 1)
    paths = []
    for k in range(copies):
        row, col = divmod(k, side)
        folder = os.path.join(where, "assembly", f"row_{row:02d}", f"station_{col:02d}")
        os.makedirs(folder)
        for name, mesh in meshes.items():
            moved = mesh.copy()
            moved.apply_translation((col * step, row * step, 0.0))
            path = os.path.join(folder, name)
            moved.export(path)
            paths.append(path)
    return paths


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=50)
    parser.add_argument("--width", type=int, default=80)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as where:
        paths = build(where, args.copies)
        os.chdir(where)
        paths = [os.path.relpath(p, where) for p in paths]
        start = time.perf_counter()
        result = check(paths, config=None, use_cache=False)
        checked = time.perf_counter() - start
        start = time.perf_counter()
        text = render(result, "text", view=View(width=args.width))
        rendered = time.perf_counter() - start
    lines = text.splitlines()
    print("\n".join(lines[:8]), "\n...\n" + "\n".join(lines[-3:]))
    rows = [line for line in lines if re.match(r"[0-9a-f]{12}  ", line)]
    statuses = [row.split()[1] for row in rows]
    last_clash = max(k for k, s in enumerate(statuses) if s == "interference")
    first_touch = min((k for k, s in enumerate(statuses) if s == "touching"), default=len(rows))
    names = [cell for row in rows for cell in row.split()[2:4]]
    full = {n for f in result.findings for n in (f.a, f.b)}
    widest = max(len(line) for line in lines)
    clashes = statuses.count("interference")
    print(f"\nparts {len(result.parts)}, findings {len(rows)}, {clashes} interference")
    print(f"interferences before touching rows: {last_clash < first_touch}")
    print(f"widest line: {widest} columns (limit {args.width}): {widest <= args.width}")
    distinct_cells = len(set(names))
    print(f"distinct names shown: {distinct_cells} for {len(full)} distinct parts in findings")
    print(f"render / check time: {rendered:.3f} s / {checked:.1f} s = {rendered / checked:.4f}")
    groups = clash_groups(result.findings)
    print("clash groups: " + ", ".join(f"{g.kind} of {len(g.members)} {g.status}" for g in groups))
    is_one_pattern = [(g.kind, len(g.members)) for g in groups] == [("pattern", clashes)]
    print(f"the copies' interferences are one pattern group: {is_one_pattern}")
    ok = last_clash < first_touch and widest <= args.width and distinct_cells == len(full)
    ok = ok and is_one_pattern
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
