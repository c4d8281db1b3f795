"""The README's first command as a new user meets it: install, then a cold and a warm run.

Run from the repository root::

    python bench/first_run.py             # a fresh virtual environment, `pip install .` into it
    python bench/first_run.py --no-venv   # the current environment (compile caches cleared)
    python bench/first_run.py --rounds 3  # repeat the cold/warm/peer runs, report medians

With a fresh environment the script creates a virtual environment in a temporary directory,
runs ``pip install REPO`` into it (timed; pip's own download and wheel caches are used, as on a
machine that has installed Python packages before), then times whole processes of that
environment's console script::

    meshcheck sample_meshes/*.stl --cache-dir EMPTY_DIR     (cold: first run after install)
    meshcheck sample_meshes/*.stl --cache-dir SAME_DIR      (warm: decompositions cached)

and, in the same run, the peer: a process that loads the same STL files with trimesh and runs
``CollisionManager.in_collision_internal`` (FCL; needs python-fcl, a dev dependency, in the
interpreter running this script). With ``--no-venv`` the installed ``meshcheck`` of the current
environment is timed instead, with an empty ``--cache-dir``: the compiled kernels keep no cache
of their own. (To time a checkout from before the kernels were compiled at install, when numba
compiled them at first use, run its environment's Python on this script with ``--no-venv`` and
``NUMBA_CACHE_DIR`` pointing at an empty directory.)

Each later round repeats the cold run with a new empty cache directory (the environment is no
longer fresh then: the rows after the first measure a cold decomposition cache only).

It prints wall and CPU times (CPU: the process and its worker processes, which a machine shared
with other work disturbs less), their ratios against CollisionManager ("/ CM"), and checks that
the cold and warm reports are identical.
"""

from __future__ import annotations

import argparse
import glob
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

FCL_SCRIPT = """
import sys, trimesh
manager = trimesh.collision.CollisionManager()
for p in sys.argv[1:]:
    manager.add_object(p, trimesh.load_mesh(p))
hit, names = manager.in_collision_internal(return_names=True)
print(len(names))
"""


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], env: dict | None = None) -> tuple[float, float, int, str]:
    """Wall seconds, CPU seconds (the process and its waited-for descendants), exit status and
    stdout of ``cmd`` run from the repository root."""
    t, c = time.perf_counter(), _children_cpu()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    wall, cpu = time.perf_counter() - t, _children_cpu() - c
    if "Traceback" in r.stderr:
        sys.stderr.write(r.stderr)
    return wall, cpu, r.returncode, r.stdout


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-venv", action="store_true", help="time the current environment")
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args(argv)
    try:
        import fcl  # noqa: F401
    except ImportError:
        sys.exit("error: python-fcl is not installed (pip install python-fcl)")

    files = sorted(
        os.path.relpath(p, ROOT) for p in glob.glob(os.path.join(ROOT, "sample_meshes", "*.stl"))
    )
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ)
        env["XDG_CACHE_HOME"] = os.path.join(tmp, "xdg")  # no user cache of any tool
        if args.no_venv:
            script = os.path.join(os.path.dirname(sys.executable), "meshcheck")
            install = None
        else:
            venv = os.path.join(tmp, "venv")
            subprocess.run([sys.executable, "-m", "venv", venv], check=True)
            pip = os.path.join(venv, "bin", "pip")
            t = time.perf_counter()
            subprocess.run([pip, "install", "-q", ROOT], check=True, stderr=subprocess.DEVNULL)
            install = time.perf_counter() - t
            script = os.path.join(venv, "bin", "meshcheck")
        cold, warm, peer = [], [], []
        for r in range(args.rounds):
            cache = os.path.join(tmp, f"cache{r}")
            c = timed([script, *files, "--cache-dir", cache], env)
            w = timed([script, *files, "--cache-dir", cache], env)
            p = timed([sys.executable, "-c", FCL_SCRIPT, *files])
            assert c[2] == w[2] == 1, (
                f"expected exit status 1 (the oversized bolt), got {c[2]}, {w[2]}"
            )
            assert c[3] == w[3], "cold and warm reports differ"
            assert p[2] == 0, "CollisionManager run failed"
            cold.append(c[:2])
            warm.append(w[:2])
            peer.append(p[:2])

    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cores, {len(files)} sample parts")
    if install is not None:
        print(f"pip install . into a fresh venv: {install:.1f} s")
    print(f"{'run (medians)':<46}{'wall s':>7}{'/ CM':>7}{'CPU s':>8}{'/ CM':>7}")
    base = [statistics.median(x[i] for x in peer) for i in (0, 1)]
    first = "meshcheck, first run (cold)" if install is not None else "meshcheck, cold caches"
    rows = [(first, cold[:1]), ("meshcheck, warm", warm), ("CollisionManager (trimesh, FCL)", peer)]
    if args.rounds > 1:
        rows.insert(1, ("meshcheck, cold decomposition cache only", cold[1:]))
    for name, runs in rows:
        wall, cpu = (statistics.median(x[i] for x in runs) for i in (0, 1))
        print(f"{name:<46}{wall:>7.2f}{wall / base[0]:>6.2f}x{cpu:>8.2f}{cpu / base[1]:>6.2f}x")


if __name__ == "__main__":
    main()
