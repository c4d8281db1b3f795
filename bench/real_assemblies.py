"""Public real assemblies: meshcheck cold and warm against trimesh's CollisionManager, one run.

Nothing is fetched at run time. Prepare a folder once (figures: docs/internals/benchmarks.md)::

    DATA=~/meshcheck-data
    git clone --depth 1 https://github.com/moveit/moveit_resources   $DATA/moveit_resources
    git clone --depth 1 https://github.com/3MFConsortium/3mf-samples $DATA/3mf-samples
    git clone --depth 1 https://github.com/mikedh/trimesh             $DATA/trimesh
    python bench/real_assemblies.py prepare $DATA      # writes $DATA/prepared/*.glb
    python bench/real_assemblies.py run $DATA [--repeat 3] [--jobs N] [--only pr2 ...]

``prepare`` writes two GLB files: the PR2's collision meshes at zero joints
(``bench/urdf_scene.py``: CollisionManager reads no URDF, so both sides read this GLB) and
``cycloidal.3DXML`` as trimesh reads it (instances kept: one glTF mesh placed by several
nodes). The licence files stay in the clones beside the meshes (moveit_resources: BSD,
``pr2_description/package.xml``; 3mf-samples: ``LICENSE``; trimesh: ``LICENSE.md``).

``run`` times, per assembly and repeat, whole processes in the same run:

- cold: ``meshcheck --format json --cache-dir DIR FILE`` with DIR empty and a fresh
  ``MESHCHECK_CACHE_SECRET`` (the console script beside the running Python, or ``--meshcheck``);
- warm: the same command again (caches filled by the cold run);
- CollisionManager: a process that loads the same file with trimesh, adds every node's mesh at
  its placement and runs ``in_collision_internal(return_names=True)``.

It prints the times and the ratios cold/CM and warm/CM, and checks that the cold and warm JSON
reports are byte-identical (exit status 1 when any pair of them differs).
"""

from __future__ import annotations

import argparse
import os
import secrets
import shlex
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

#: name -> file below the data folder
ASSEMBLIES = {
    "pr2": "prepared/pr2_zero_joints.glb",
    "dodeca_chain_loop": "3mf-samples/examples/core/dodeca_chain_loop.3mf",
    "cycloidal": "prepared/cycloidal.glb",
    "milk_truck": "trimesh/models/CesiumMilkTruck.glb",
}

_SCRIPT = os.path.join(os.path.dirname(sys.executable), "meshcheck")
MESHCHECK = [_SCRIPT] if os.path.exists(_SCRIPT) else [sys.executable, "-m", "meshcheck"]

CM_SCRIPT = """
import json, sys, trimesh
scene = trimesh.load(sys.argv[1], force="scene")
manager = trimesh.collision.CollisionManager()
for node in scene.graph.nodes_geometry:
    transform, name = scene.graph[node]
    manager.add_object(node, scene.geometry[name], transform=transform)
hit, names = manager.in_collision_internal(return_names=True)
print(json.dumps(sorted(sorted(n) for n in names)))
"""

TIMED = """
import subprocess, sys, time
t = time.perf_counter()
r = subprocess.run(sys.argv[1:], stdout=subprocess.PIPE)
sys.stderr.write(f"TIMED {time.perf_counter() - t} {r.returncode}\\n")
sys.stdout.buffer.write(r.stdout)
"""


def prepare(data: str) -> None:
    """Write ``DATA/prepared/``: the PR2 at zero joints and cycloidal.3DXML, both as GLB."""
    import trimesh

    sys.path.insert(0, HERE)
    from urdf_scene import urdf_to_glb

    out = os.path.join(data, "prepared")
    os.makedirs(out, exist_ok=True)
    package = os.path.join(data, "moveit_resources", "pr2_description")
    count = urdf_to_glb(
        os.path.join(package, "urdf", "robot.xml"),
        package,
        os.path.join(out, "pr2_zero_joints.glb"),
    )
    print(f"pr2_zero_joints.glb: {count} collision meshes")
    scene = trimesh.load(os.path.join(data, "trimesh", "models", "cycloidal.3DXML"))
    scene.export(os.path.join(out, "cycloidal.glb"))
    print(f"cycloidal.glb: {len(scene.graph.nodes_geometry)} nodes, {len(scene.geometry)} meshes")


def timed(cmd: list[str], env: dict | None = None) -> tuple[float, int, bytes]:
    """Wall seconds, exit status and stdout of the process ``cmd``."""
    r = subprocess.run([sys.executable, "-c", TIMED, *cmd], capture_output=True, cwd=ROOT, env=env)
    err = r.stderr.decode(errors="replace")
    line = [s for s in err.splitlines() if s.startswith("TIMED ")][-1].split()
    if "Traceback" in err or int(line[2]) not in (0, 1):
        sys.stderr.write(err)
    return float(line[1]), int(line[2]), r.stdout


def run_one(path: str, meshcheck: list[str], jobs: int | None) -> dict:
    """One cold, one warm and one CollisionManager run of ``path``."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [*meshcheck, "--format", "json", "--cache-dir", os.path.join(tmp, "cache")]
        if jobs:
            cmd += ["--jobs", str(jobs)]
        env = dict(os.environ, MESHCHECK_CACHE_SECRET=secrets.token_hex(16))
        cold = timed([*cmd, path], env)
        warm = timed([*cmd, path], env)
    cm = timed([sys.executable, "-c", CM_SCRIPT, path])
    if cm[1] != 0:  # a failed load is no time to compare against (trimesh's 3MF needs networkx)
        sys.exit(f"error: {path}: CollisionManager's run failed (above); no ratio without it")
    return {
        "cold": cold[0],
        "warm": warm[0],
        "cm": cm[0],
        "status": (cold[1], warm[1]),
        "identical": cold[2] == warm[2],
    }


def run(data: str, names: list[str], repeat: int, meshcheck: list[str], jobs: int | None) -> int:
    print(
        f"{'assembly':18s} {'rep':>3s} {'cold s':>7s} {'warm s':>7s} {'CM s':>6s} "
        f"{'cold/CM':>7s} {'warm/CM':>7s} {'exit':>4s} identical"
    )
    differ = 0
    for name in names:
        path = os.path.join(data, ASSEMBLIES[name])
        if not os.path.exists(path):
            sys.exit(f"error: {path}: missing; see the docstring (prepare the data folder)")
        rows = []
        for k in range(repeat):
            r = run_one(path, meshcheck, jobs)
            rows.append(r)
            differ += not r["identical"]
            print(
                f"{name:18s} {k + 1:3d} {r['cold']:7.2f} {r['warm']:7.2f} {r['cm']:6.2f} "
                f"{r['cold'] / r['cm']:7.2f} {r['warm'] / r['cm']:7.2f} "
                f"{r['status'][0]:4d} {'yes' if r['identical'] else 'NO'}",
                flush=True,
            )
        if repeat > 1:
            cold = statistics.median(r["cold"] / r["cm"] for r in rows)
            warm = statistics.median(r["warm"] / r["cm"] for r in rows)
            print(f"{name:18s} median ratios: cold/CM {cold:.2f}, warm/CM {warm:.2f}", flush=True)
    return 1 if differ else 0


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("prepare", help="convert the PR2 URDF and cycloidal.3DXML to GLB")
    p.add_argument("data")
    r = sub.add_parser("run", help="time cold, warm and CollisionManager runs")
    r.add_argument("data")
    r.add_argument("--only", nargs="*", choices=sorted(ASSEMBLIES), default=None)
    r.add_argument("--repeat", type=int, default=1)
    r.add_argument("--jobs", type=int, default=None)
    r.add_argument(
        "--meshcheck",
        default=None,
        help="command that runs meshcheck, one string (default: the console script beside this "
        "Python); e.g. 'python -P -m meshcheck' with PYTHONPATH set to time another checkout",
    )
    args = parser.parse_args(argv)
    if args.command == "prepare":
        prepare(args.data)
        return
    names = args.only or list(ASSEMBLIES)
    meshcheck = shlex.split(args.meshcheck) if args.meshcheck else MESHCHECK
    sys.exit(run(args.data, names, args.repeat, meshcheck, args.jobs))


if __name__ == "__main__":
    main()
