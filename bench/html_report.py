"""Size and time of the HTML report of a 1,000-part assembly (target: under 20 MB).

Run from the repository root::

    python bench/html_report.py               # 1000 parts (the check itself takes ~1 min cold)
    python bench/html_report.py --parts 100
    python bench/html_report.py --browser     # also time opening it in headless chromium

The assembly is ``bench/assemblies.py``'s: a few distinct parts placed many times, each copy its
own STL file in world coordinates, with planted interferences; the findings come from a real check.
Two reports are rendered from it:

- as written: translated copies of one part share their display geometry;
- all distinct: each part scaled by its own factor (1 + k/1000) about its centre, so no two
  parts share geometry: the worst case for the same triangle count;
- dense: the distinct parts, each subdivided twice (16x the triangles, ~7M): over the display
  budget, so the report decimates them.

Each is compared, in the same run, with two peers: the plain embedding of the same meshes
(float32 vertices and uint32 faces per part, base64, as a naive report would inline them) and
meshcheck's own glTF export of the assembly (``--export``: binary, needs a separate viewer).
``B/tri`` is the geometry's share (gzipped, base64) per stored triangle; the rest of the file is
the viewer (three.js, ~0.55 MB) and the JSON of parts and findings.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "scripts"))

from assemblies import write_assembly  # noqa: E402

LIMIT = 20 * 2**20


def naive_size(bodies) -> int:
    """Bytes of every part's world mesh inlined as base64 float32 vertices + uint32 faces."""
    total = 0
    for b in bodies:
        w = b.world
        raw = np.asarray(w.vertices, np.float32).nbytes + np.asarray(w.faces, np.uint32).nbytes
        total += 4 * ((raw + 2) // 3)
    return total


def distinct(bodies):
    """The same parts, each scaled about its centre by its own factor: no shared geometry."""
    from meshcheck.load import Body

    out = []
    for k, b in enumerate(bodies):
        mesh = b.mesh.copy()
        centre = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
        mesh.vertices = centre + (mesh.vertices - centre) * (1.0 + (k + 1) / 1000.0)
        out.append(Body(name=b.name, path=b.path, mesh=mesh, transform=b.transform))
    return out


def dense(bodies):
    """The same parts with 16 times the triangles (two rounds of 4-way subdivision)."""
    from meshcheck.load import Body

    out = []
    for b in bodies:
        mesh = b.mesh.subdivide().subdivide()
        out.append(Body(name=b.name, path=b.path, mesh=mesh, transform=b.transform))
    return out


def open_in_browser(path: str) -> float:
    from chromium import chromium_page

    with chromium_page(width=1280, height=720, timeout=120) as (page, errors):
        t = time.perf_counter()
        page.goto("file://" + path)
        page.wait_for_function("document.body.dataset.ready", timeout=120_000)
        seconds = time.perf_counter() - t
        if errors or page.evaluate("document.body.dataset.ready") != "true":
            raise SystemExit(f"error: {path}: the report failed in chromium: {errors}")
    return seconds


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--parts", type=int, default=1000)
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--browser", action="store_true", help="time loading in chromium")
    args = parser.parse_args(argv)

    from meshcheck.load import load_bodies
    from meshcheck.pipeline import check
    from meshcheck.reports.gltf import export_clashes
    from meshcheck.reports.html import render_html

    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)  # relative part names, as a user in the assembly's folder has them
        os.mkdir("parts")
        paths, _ = write_assembly(args.parts, "parts")
        t = time.perf_counter()
        result = check(paths, cache_dir=os.path.join(tmp, "cache"), jobs=args.jobs)
        check_s = time.perf_counter() - t
        bodies = load_bodies(paths)
        statuses = {}
        for f in result.findings:
            statuses[f.status] = statuses.get(f.status, 0) + 1
        print(f"{len(bodies)} parts, findings {statuses}, check {check_s:.1f} s")
        print(
            f"{'report':>13s} {'distinct':>8s} {'triangles':>9s} {'render s':>8s} {'MB':>6s} "
            f"{'naive MB':>8s} {'glb MB':>6s} {'/naive':>6s} {'/glb':>5s} {'B/tri':>5s} "
            f"{'browser s':>9s}  under 20 MB"
        )
        unique = distinct(bodies)
        for label, parts in (
            ("as written", bodies),
            ("all distinct", unique),
            ("dense", dense(unique)),
        ):
            t = time.perf_counter()
            text = render_html(result, parts, inputs=["parts"], version="bench")
            render_s = time.perf_counter() - t
            size = len(text.encode("utf-8"))
            export_clashes("a.glb", parts, result.findings, units=result.units)
            glb = os.path.getsize("a.glb")
            naive = naive_size(parts)
            data = json.loads(re.search(r'id="meshcheck-data">(.*?)</script>', text).group(1))
            blob = re.search(r'id="meshcheck-geometry">(.*?)<', text).group(1)
            triangles = sum(m["nf"] for m in data["meshes"])
            browser = ""
            if args.browser:
                with open("report.html", "w", encoding="utf-8") as f:
                    f.write(text)
                browser = f"{open_in_browser(os.path.abspath('report.html')):9.1f}"
            stored = len(data["meshes"])
            print(
                f"{label:>13s} {stored:8d} {triangles:9d} {render_s:8.2f} {size / 2**20:6.2f} "
                f"{naive / 2**20:8.2f} {glb / 2**20:6.2f} {size / naive:6.3f} {size / glb:5.2f} "
                f"{len(blob) / triangles:5.1f} {browser:>9s}  {'yes' if size < LIMIT else 'NO'}",
                flush=True,
            )
        os.chdir(ROOT)


if __name__ == "__main__":
    main()
