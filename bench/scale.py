"""Instanced assemblies at plant scale: meshcheck cold and warm against trimesh's CollisionManager.

Run from the repository root::

    python bench/scale.py                          # 1,020, 5,100 and 20,400 parts
    python bench/scale.py --modules 19608          # 100,001 parts (CollisionManager not run)
    python bench/scale.py --modules 200 1000 4000 19608
    python bench/scale.py --modules --step-copies 2000   # the STEP file of 2,000 bolt copies

Each assembly is one GLB in metres, as a plant's CAD export is: one mesh per distinct part (the
sample's plate, its M6 bolt, its oversized bolt and its L-bracket, ``sample_meshes/``) and a node
per module, its parts as children. A module is the plate, three bolts resting in its holes
(touching), the bracket standing on it (touching) and, in every tenth module, the oversized bolt
pushed into the fourth hole (interference). Modules stand on a floor grid 150 x 100 mm apart,
every other row turned half a turn. So ``m`` modules make ``5.1 m`` parts, ``4 m`` touching
findings and ``m / 10`` interferences, whatever ``m``: six distinct situations.

For each size it times, in the same run, whole processes (start-up, loading, checking), each
with its peak resident memory (``ru_maxrss`` of the children):

- ``meshcheck`` cold: ``meshcheck --no-config --format json --cache-dir DIR FILE``, DIR empty;
- ``meshcheck`` warm: the same command again (every pair verdict and decomposition cached);
- CollisionManager: a process that loads the GLB with trimesh and adds every placed mesh to
  ``trimesh.collision.CollisionManager`` (FCL), then ``in_collision_internal``. Its work grows
  faster than the parts (each ``add_object`` updates FCL's tree), so it is only run up to
  ``--peer-max`` parts.

It prints wall times, peak memory, the ratios to CollisionManager, the machine's load averages
before and after each size (the machine may be shared: compare ratios measured in one run), and
checks the findings: every planted interference found, every resting bolt and bracket touching,
nothing else, and the warm report identical to the cold one.

``--step-copies N`` also times a STEP file (AP214, written by OpenCASCADE: the ``dev`` extra) of
one product, the sample's M6 bolt as ``sample_meshes/make_step_sample.py`` builds it, placed N
times at one spot, cold and warm, against CollisionManager adding the bolt's tessellation N
times; the one finding expected is a duplicate of N copies.
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import sys
import tempfile

import numpy as np
import trimesh

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "sample_meshes"))

from assemblies import MESHCHECK, timed  # noqa: E402

SAMPLES = os.path.join(ROOT, "sample_meshes")
HOLES = [(-35.0, -15.0), (-35.0, 15.0), (35.0, -15.0), (35.0, 15.0)]  # mm, the plate's frame
PITCH = (0.150, 0.100)  # module spacing on the floor, metres
PLANTED_EVERY = 10

PEER_SCRIPT = """
import json, sys, trimesh
scene = trimesh.load(sys.argv[1], force="scene")
manager = trimesh.collision.CollisionManager()
for node in scene.graph.nodes_geometry:
    transform, geometry = scene.graph[node]
    manager.add_object(node, scene.geometry[geometry], transform)
hit, names = manager.in_collision_internal(return_names=True)
print(json.dumps(sorted(sorted(n) for n in names)))
"""

STEP_PEER_SCRIPT = """
import sys, numpy as np, trimesh
mesh = trimesh.load_mesh(sys.argv[1])
manager = trimesh.collision.CollisionManager()
for k in range(int(sys.argv[2])):
    manager.add_object(f"bolt{k}", mesh, np.eye(4))
hit, names = manager.in_collision_internal(return_names=True)
print(len(names))
"""


def parts() -> dict[str, trimesh.Trimesh]:
    """The distinct parts, each in its own frame (a bolt's axis on z), millimetres."""

    def load(name, hole=None):
        mesh = trimesh.load_mesh(os.path.join(SAMPLES, name))
        if hole is not None:
            mesh.apply_translation([-hole[0], -hole[1], 0.0])
        return mesh

    return {
        "plate": load("plate.stl"),
        "bolt": load("bolt_m6_a.stl", HOLES[0]),
        "fat_bolt": load("bolt_m8_oversized.stl", HOLES[3]),
        "bracket": load("bracket.stl"),
    }


def write_plant(path: str, modules: int) -> dict:
    """Write ``modules`` modules as one GLB; return the expected findings by node name pair."""
    shapes = parts()
    names = list(shapes)
    blob, views, accessors, meshes = bytearray(), [], [], []
    for k, name in enumerate(names):
        v = np.asarray(shapes[name].vertices * 1e-3, dtype=np.float32)  # glTF is in metres
        f = np.asarray(shapes[name].faces, dtype=np.uint32).ravel()
        for array in (v, f):
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
            blob += array.tobytes()
        accessors.append({
            "bufferView": 2 * k, "componentType": 5126, "count": len(v), "type": "VEC3",
            "min": v.min(axis=0).tolist(), "max": v.max(axis=0).tolist(),
        })  # fmt: skip
        accessors.append(
            {"bufferView": 2 * k + 1, "componentType": 5125, "count": f.size, "type": "SCALAR"}
        )
        meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": 2 * k},
                                                      "indices": 2 * k + 1}]})  # fmt: skip
    nodes, roots, expected = [], [], {}
    side = int(np.ceil(np.sqrt(modules)))
    for m in range(modules):
        row, column = divmod(m, side)
        turned = row % 2 == 1  # half a turn about z
        module = f"m{m:06d}"
        placed = [("plate", "plate", (0.0, 0.0))]
        placed += [(f"bolt{h}", "bolt", hole) for h, hole in enumerate(HOLES[:3])]
        placed.append(("bracket", "bracket", (0.0, 0.0)))
        if m % PLANTED_EVERY == 0:
            placed.append(("fat_bolt", "fat_bolt", HOLES[3]))
        children = []
        for name, mesh, (x, y) in placed:
            nodes.append({"name": f"{module}/{name}", "mesh": names.index(mesh),
                          "translation": [1e-3 * x, 1e-3 * y, 0.0]})  # fmt: skip
            children.append(len(nodes) - 1)
            if name != "plate":
                status = "interference" if mesh == "fat_bolt" else "touching"
                expected[(f"{module}/{name}", f"{module}/plate")] = status
        nodes.append({
            "name": module,
            "translation": [PITCH[0] * column, PITCH[1] * row, 0.0],
            "rotation": [0.0, 0.0, 1.0, 0.0] if turned else [0.0, 0.0, 0.0, 1.0],
            "children": children,
        })  # fmt: skip
        roots.append(len(nodes) - 1)
    header = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    with open(path, "wb") as f:
        f.write(b"glTF" + struct.pack("<II", 2, 28 + len(text) + len(blob)))
        f.write(struct.pack("<I", len(text)) + b"JSON" + text)
        f.write(struct.pack("<I", len(blob)) + b"BIN\0" + bytes(blob))
    return expected


def load_averages() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def run_size(modules: int, peer_max: int, jobs: int | None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "plant.glb")
        expected = write_plant(path, modules)
        count = sum(1 + 4 + (m % PLANTED_EVERY == 0) for m in range(modules))
        cache = os.path.join(tmp, "cache")
        cmd = [*MESHCHECK, "--no-config", "--format", "json", "--cache-dir", cache, path]
        if jobs:
            cmd += ["--jobs", str(jobs)]
        env = dict(os.environ, MESHCHECK_CACHE_SECRET="bench-scale")
        before = load_averages()
        cold = timed(cmd, env)
        warm = timed(cmd, env)
        peer = None
        if count <= peer_max:
            peer = timed([sys.executable, "-c", PEER_SCRIPT, path])
        after = load_averages()

        report = json.loads(cold[3])
        assert json.loads(warm[3]) == report, "the warm report differs from the cold one"
        found = {
            (r["a"].split("#", 1)[1], r["b"].split("#", 1)[1]): r["status"]
            for r in report["results"]
        }
        out = {
            "modules": modules,
            "parts": count,
            "cold": cold,
            "warm": warm,
            "peer": peer,
            "load": (before, after),
            "exact": found == expected,
            "findings": len(found),
            "groups": len(report["groups"]),
        }
        if peer is not None:
            collided = {tuple(sorted(p)) for p in json.loads(peer[3])}
            planted = {tuple(sorted(p)) for p, s in expected.items() if s == "interference"}
            out["peer_found"] = f"{len(planted & collided)} of {len(planted)}"
            out["peer_pairs"] = len(collided)
        return out


def run_step(copies: int) -> dict:
    """Time the STEP file of ``copies`` coincident bolts: cold, warm and CollisionManager."""
    from make_step_sample import bolt
    from step_writer import write_step

    from meshcheck.load import load_bodies

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bolts.step")
        one = os.path.join(tmp, "bolt.step")
        sys.stdout.flush()
        saved = os.dup(1)  # OpenCASCADE's writer prints its statistics on the process's stdout
        try:
            with open(os.devnull, "w") as quiet:
                os.dup2(quiet.fileno(), 1)
            write_step(path, {"bolt": bolt(3.0)}, [("bolt", np.eye(4))] * copies)
            write_step(one, {"bolt": bolt(3.0)}, [("bolt", np.eye(4))])
        finally:
            os.dup2(saved, 1)
            os.close(saved)
        (body,) = load_bodies([one])
        stl = os.path.join(tmp, "bolt.stl")
        body.world.export(stl)
        cache = os.path.join(tmp, "cache")
        cmd = [*MESHCHECK, "--no-config", "--format", "json", "--cache-dir", cache, path]
        env = dict(os.environ, MESHCHECK_CACHE_SECRET="bench-scale")
        before = load_averages()
        cold = timed(cmd, env)
        warm = timed(cmd, env)
        peer = timed([sys.executable, "-c", STEP_PEER_SCRIPT, stl, str(copies)])
        after = load_averages()
        report = json.loads(cold[3])
        assert json.loads(warm[3]) == report, "the warm report differs from the cold one"
        statuses = [r["status"] for r in report["results"]]
        return {
            "copies": copies,
            "cold": cold,
            "warm": warm,
            "peer": peer,
            "load": (before, after),
            "exact": statuses == ["duplicate"],
            "peer_pairs": int(peer[3]),
        }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--modules", nargs="*", type=int, default=[200, 1000, 4000])
    parser.add_argument(
        "--peer-max", type=int, default=25000, help="largest assembly CollisionManager runs on"
    )
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument(
        "--step-copies", type=int, default=None, help="also time a STEP file of this many bolts"
    )
    args = parser.parse_args(argv)
    print(f"{os.cpu_count()} cores; wall seconds of whole processes, peak resident MiB")
    print(
        f"{'parts':>7} {'cold s':>7} {'warm s':>7} {'CM s':>7} {'cold/CM':>8} {'warm/CM':>8} "
        f"{'cold MiB':>8} {'warm MiB':>8} {'CM MiB':>7}  findings (exact)  load before/after"
    )
    failed = False
    for modules in args.modules:
        r = run_size(modules, args.peer_max, args.jobs)
        cold, warm, peer = r["cold"], r["warm"], r["peer"]
        if peer is not None:
            ratios = f"{cold[0] / peer[0]:8.2f} {warm[0] / peer[0]:8.2f}"
            peer_text = f"{peer[0]:7.1f}"
            peer_mb = f"{peer[1]:7.0f}"
        else:
            ratios, peer_text, peer_mb = f"{'-':>8} {'-':>8}", f"{'not run':>7}", f"{'-':>7}"
        print(
            f"{r['parts']:7d} {cold[0]:7.1f} {warm[0]:7.1f} {peer_text} {ratios} "
            f"{cold[1]:8.0f} {warm[1]:8.0f} {peer_mb}  {r['findings']:6d} ({r['exact']})"
            f"  {r['load'][0]} / {r['load'][1]}"
        )
        if peer is not None:
            print(
                f"{'':7} CollisionManager: {r['peer_found']} planted interferences among its "
                f"{r['peer_pairs']} colliding pairs"
            )
        failed |= not r["exact"]
    if args.step_copies:
        r = run_step(args.step_copies)
        cold, warm, peer = r["cold"], r["warm"], r["peer"]
        print(
            f"STEP, {r['copies']} copies of one bolt at one spot: cold {cold[0]:.1f} s "
            f"({cold[1]:.0f} MiB), warm {warm[0]:.1f} s, CollisionManager {peer[0]:.1f} s "
            f"({peer[1]:.0f} MiB, {r['peer_pairs']} colliding pairs); cold/CM "
            f"{cold[0] / peer[0]:.2f}; one duplicate finding ({r['exact']})  "
            f"load {r['load'][0]} / {r['load'][1]}"
        )
        failed |= not r["exact"]
    if failed:
        raise SystemExit("meshcheck's findings are not the planted ones")


if __name__ == "__main__":
    main()
