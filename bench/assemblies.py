"""Assemblies of 10, 100 (and 1000) parts: meshcheck against trimesh's CollisionManager (FCL).

Run from the repository root::

    python bench/assemblies.py              # 10 and 100 parts
    python bench/assemblies.py --big        # also 1000 parts (several minutes)
    python bench/assemblies.py --sizes 10   # just one size

Each assembly is a grid of cells; a cell is a perforated plate with pins in its holes (0.3 mm
radial clearance), a bolt whose head rests on the plate, and slotted L-brackets standing on it
(touching). A handful of distinct geometries are placed many times, each copy written as its own
STL file in world coordinates, as users have them. Planted clashes: every fifth cell has an
oversized pin (interference) and a bracket sunk 0.5 mm into its plate (interference); cell 0 also
holds a small block buried inside its plate, touching no surface (interference that a
triangle-only test misses).

For each size the script times, in the same run, whole processes (start-up, loading, checking):

- ``meshcheck`` cold: ``meshcheck --format json --cache-dir DIR FILES`` with DIR empty (the
  console script beside the running Python, else ``python -m meshcheck``);
- ``meshcheck`` warm: the same command again (decompositions and pair verdicts cached);
- ``meshcheck`` new key: the same command with another ``MESHCHECK_CACHE_SECRET``, so no cached
  verdict is usable and decompositions are checked, not trusted (a CI job without the secret,
  its cache restored: what every warm run cost before verdicts were cached);
- FCL: a process that loads the same STL files with trimesh and runs
  ``CollisionManager.in_collision_internal(return_names=True)``.

It prints wall time, peak resident memory (largest process, ``ru_maxrss`` of the children), their
ratios, and how the pairs found agree: meshcheck's interference pairs against FCL's colliding pairs
(FCL also reports touching pairs; a planted clash FCL does not report is a miss, a pair it reports
that meshcheck finds clear is a false alarm).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import trimesh

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

from coacd_settings import _box, _cyl, _slot, _trimesh  # noqa: E402

PITCH = 20.0  # hole pitch on the plates, mm
HOLES_X, HOLES_Y = 4, 3
PLATE = (HOLES_X * PITCH, HOLES_Y * PITCH, 8.0)
CELL = 140.0  # cell spacing; cells never meet


def geometries() -> dict[str, trimesh.Trimesh]:
    """The distinct parts, frame-local, millimetres."""
    import manifold3d as m

    holes = [
        _cyl(3.3, -1, 9, (i + 0.5) * PITCH, (j + 0.5) * PITCH, 48)
        for i in range(HOLES_X)
        for j in range(HOLES_Y)
    ]
    plate = _box([0, 0, 0], list(PLATE)) - m.Manifold.batch_boolean(holes, m.OpType.Add)
    pin = _cyl(3.0, -6, 14, 0, 0, 48)
    fat_pin = _cyl(3.5, -6, 14, 0, 0, 48)
    bolt = _cyl(5.5, 8, 12, 0, 0, 48) + _cyl(3.0, -4, 8, 0, 0, 48)
    bracket = _box([0, 0, 0], [30, 16, 4]) + _box([0, 0, 4], [4, 16, 30])
    bracket = bracket - _slot(12, 8, 24, 8, 2.5, -1, 5, 32)
    buried = _box([0, 0, 0], [4, 4, 4])
    return {
        "plate": _trimesh(plate),
        "pin": _trimesh(pin),
        "fat_pin": _trimesh(fat_pin),
        "bolt": _trimesh(bolt),
        "bracket": _trimesh(bracket),
        "buried": _trimesh(buried),
    }


def cell_parts(cell: int) -> list[tuple[str, np.ndarray]]:
    """(geometry, translation) of the parts of one cell, before the cell's own offset."""
    holes = [((i + 0.5) * PITCH, (j + 0.5) * PITCH) for j in range(HOLES_Y) for i in range(HOLES_X)]
    parts = [("plate", (0.0, 0.0, 0.0))]
    planted = cell % 5 == 0
    for k, (x, y) in enumerate(holes[:6]):
        parts.append(("fat_pin" if planted and k == 0 else "pin", (x, y, 0.0)))
    parts.append(("bolt", (*holes[6], 0.0)))
    sink = -0.5 if planted else 0.0
    parts.append(("bracket", (2.0, 62.0 - 16.0 - 0.5, 8.0 + sink)))  # on the plate's far edge
    parts.append(("bracket", (44.0, 62.0 - 16.0 - 0.5, 8.0)))
    if cell == 0:
        parts.append(("buried", (PITCH - 2.0, 2.0, 2.0)))  # between holes, inside the plate
    return [(g, np.asarray(t, dtype=np.float64)) for g, t in parts]


def write_assembly(size: int, directory: str) -> tuple[list[str], set, set]:
    """Write about ``size`` STL files; return paths, expected clashes and expected contacts."""
    shapes = geometries()
    paths, clashes = [], set()
    cells = int(np.ceil(size / 10))
    side = int(np.ceil(np.sqrt(cells)))
    for cell in range(cells):
        offset = np.array([(cell % side) * CELL, (cell // side) * CELL, 0.0])
        names = []
        for k, (geom, t) in enumerate(cell_parts(cell)):
            if len(paths) >= size and geom != "buried":
                break
            mesh = shapes[geom].copy()
            mesh.apply_translation(offset + t)
            path = os.path.join(directory, f"c{cell:03d}_{k:02d}_{geom}.stl")
            mesh.export(path)
            paths.append(path)
            names.append((geom, path))
        plate = names[0][1]
        for geom, path in names:
            if geom in ("fat_pin", "buried"):
                clashes.add(tuple(sorted((plate, path))))
        if cell % 5 == 0:
            sunk = [p for g, p in names if g == "bracket"][:1]
            clashes.update(tuple(sorted((plate, p))) for p in sunk)
    return paths, clashes


# The console script, as users run it (``python -m meshcheck`` is ~0.2 s slower to start: under
# -m, importing scipy.special takes ~0.2 s longer for reasons of scipy's own).
_SCRIPT = os.path.join(os.path.dirname(sys.executable), "meshcheck")
MESHCHECK = [_SCRIPT] if os.path.exists(_SCRIPT) else [sys.executable, "-m", "meshcheck"]

FCL_SCRIPT = """
import json, sys, trimesh
paths = json.load(open(sys.argv[1]))
manager = trimesh.collision.CollisionManager()
for p in paths:
    manager.add_object(p, trimesh.load_mesh(p))
hit, names = manager.in_collision_internal(return_names=True)
print(json.dumps(sorted(sorted(n) for n in names)))
"""

TIMED = """
import resource, subprocess, sys, time
t = time.perf_counter()
r = subprocess.run(sys.argv[1:], stdout=subprocess.PIPE)
wall = time.perf_counter() - t
rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
sys.stderr.write(f"TIMED {wall} {rss} {r.returncode}\\n")
sys.stdout.buffer.write(r.stdout)
"""


def timed(cmd: list[str], env: dict | None = None) -> tuple[float, float, int, str]:
    """Wall seconds, peak RSS (MB, largest descendant), exit status and stdout of ``cmd``."""
    r = subprocess.run(
        [sys.executable, "-c", TIMED, *cmd], capture_output=True, text=True, cwd=ROOT, env=env
    )
    line = [s for s in r.stderr.splitlines() if s.startswith("TIMED ")][-1].split()
    if "Traceback" in r.stderr:
        sys.stderr.write(r.stderr)
    return float(line[1]), int(line[2]) / 1024.0, int(line[3]), r.stdout


def run_size(size: int, jobs: int | None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        mesh_dir = os.path.join(tmp, "meshes")
        cache_dir = os.path.join(tmp, "cache")
        os.makedirs(mesh_dir)
        paths, clashes = write_assembly(size, mesh_dir)
        list_file = os.path.join(tmp, "paths.json")
        with open(list_file, "w") as f:
            json.dump(paths, f)

        cmd = [*MESHCHECK, "--format", "json", "--cache-dir", cache_dir]
        if jobs:
            cmd += ["--jobs", str(jobs)]
        env = dict(os.environ, MESHCHECK_CACHE_SECRET="bench-assemblies")
        cold = timed([*cmd, *paths], env)
        warm = timed([*cmd, *paths], env)
        new_key = timed([*cmd, *paths], dict(env, MESHCHECK_CACHE_SECRET="bench-other-key"))
        fcl = timed([sys.executable, "-c", FCL_SCRIPT, list_file])

        report = json.loads(warm[3])
        assert json.loads(cold[3]) == report, "cold and warm reports differ"
        assert json.loads(new_key[3]) == report, "a run with another key reports otherwise"
        found = {tuple(sorted((r["a"], r["b"]))): r["status"] for r in report["results"]}
        interference = {p for p, s in found.items() if s == "interference"}
        fcl_pairs = {tuple(p) for p in json.loads(fcl[3])}
        return {
            "size": len(paths),
            "cold": cold,
            "warm": warm,
            "new_key": new_key,
            "fcl": fcl,
            "planted": len(clashes),
            "meshcheck_found": len(interference & clashes),
            "meshcheck_extra": sorted(interference - clashes),
            "touching": sum(1 for s in found.values() if s == "touching"),
            "fcl_found": len(fcl_pairs & clashes),
            "fcl_missed": sorted(clashes - fcl_pairs),
            "fcl_pairs": len(fcl_pairs),
            "fcl_false": sorted(fcl_pairs - set(found)),
        }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", nargs="*", type=int, default=None)
    parser.add_argument("--big", action="store_true", help="also run 1000 parts")
    parser.add_argument("--jobs", type=int, default=None)
    args = parser.parse_args(argv)
    sizes = args.sizes or ([10, 100, 1000] if args.big else [10, 100])

    print(
        f"{'parts':>5s} {'cold s':>7s} {'warm s':>7s} {'newkey s':>8s} {'fcl s':>6s} "
        f"{'warm/fcl':>8s} {'newkey/fcl':>10s} {'cold MB':>7s} {'warm MB':>7s} {'newkey MB':>9s} "
        f"{'fcl MB':>6s}  clashes: planted / meshcheck / fcl"
    )
    for size in sizes:
        r = run_size(size, args.jobs)
        (cs, cm, _, _), (ws, wm, _, _) = r["cold"], r["warm"]
        (ns, nm, _, _), (fs, fm, _, _) = r["new_key"], r["fcl"]
        print(
            f"{r['size']:5d} {cs:7.2f} {ws:7.2f} {ns:8.2f} {fs:6.2f} {ws / fs:8.2f} "
            f"{ns / fs:10.2f} {cm:7.0f} {wm:7.0f} {nm:9.0f} {fm:6.0f}  {r['planted']} / "
            f"{r['meshcheck_found']} / {r['fcl_found']}",
            flush=True,
        )
        print(
            f"      meshcheck: {r['touching']} touching, extra interference "
            f"{len(r['meshcheck_extra'])}; fcl: {r['fcl_pairs']} colliding pairs, missed "
            f"{[os.path.basename(b) for _, b in r['fcl_missed']]}, reported but clear in "
            f"meshcheck {len(r['fcl_false'])}",
            flush=True,
        )


if __name__ == "__main__":
    main()
