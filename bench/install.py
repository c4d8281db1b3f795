"""Installing the built wheel against installing from source, each into a fresh venv.

Command::

    python bench/install.py             # (options: --rounds R)

Times, in one run:

* ``pip wheel . --no-deps -w DIR``: building the wheel from this checkout (compiles the kernels);
* ``pip install WHEEL`` into a fresh virtual environment, with ``CC``, ``CXX`` and ``PATH`` set
  so that any attempt to compile fails: the wheel installs without a compiler;
* the peer, ``pip install .`` into another fresh virtual environment (README's first command:
  compiles the kernels during the install);
* ``meshcheck sample_meshes/*.stl`` with each environment's console script (must exit 1: the
  oversized bolt) and with the reports compared byte for byte.

Each build starts from a clean copy of the checkout (pip builds in the source tree and would
reuse an earlier build's objects). Dependencies come from pip's cache, as on a machine that has
installed Python packages before: both installs pay the same for them, so the difference is the
compile. Each round uses new
environments; figures are medians over rounds of wall time and of CPU time (the process and its
children: what a machine shared with other work disturbs least), and the median over rounds of
the wheel install's time divided by the source install's.
"""

from __future__ import annotations

import argparse
import glob
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = "Scripts" if sys.platform == "win32" else "bin"


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], **kwargs) -> tuple[tuple[float, float], subprocess.CompletedProcess]:
    """Run ``cmd``: ((wall seconds, CPU seconds of it and its children), the result)."""
    start, cpu = time.perf_counter(), children_cpu()
    done = subprocess.run(cmd, capture_output=True, text=True, **kwargs)
    return (time.perf_counter() - start, children_cpu() - cpu), done


def fresh_venv(where: str) -> str:
    """A new virtual environment; returns its bin directory."""
    subprocess.run([sys.executable, "-m", "venv", where], check=True)
    return os.path.join(where, BIN)


def no_compiler_env(tmp: str) -> dict[str, str]:
    """The environment with every way to a C/C++ compiler failing (a machine without g++)."""
    fake = os.path.join(tmp, "no-compiler")
    os.makedirs(fake, exist_ok=True)
    for name in ("cc", "c++", "gcc", "g++", "clang", "clang++"):
        path = os.path.join(fake, name)
        with open(path, "w") as f:
            f.write("#!/bin/sh\necho 'no compiler here' >&2\nexit 1\n")
        os.chmod(path, 0o755)
    return {
        **os.environ,
        "CC": "false",
        "CXX": "false",
        "PATH": fake + os.pathsep + os.environ["PATH"],
    }


def sample(bin_dir: str) -> tuple[tuple[float, float], str]:
    """The sample through this environment's meshcheck (must exit 1): seconds, text report."""
    files = sorted(glob.glob(os.path.join(ROOT, "sample_meshes", "*.stl")))
    seconds, done = timed([os.path.join(bin_dir, "meshcheck"), *files, "--no-cache"], cwd=ROOT)
    if done.returncode != 1:
        sys.exit(f"error: the sample exited {done.returncode}, not 1:\n{done.stderr}")
    return seconds, done.stdout


def clean_copy(where: str) -> str:
    """The checkout without build products: pip builds in the tree, and would reuse them."""
    junk = (".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", "*.so", "*.pyd")
    shutil.copytree(ROOT, where, ignore=shutil.ignore_patterns(*junk))
    return where


def one_round(tmp: str) -> dict[str, float]:
    wheels = os.path.join(tmp, "wheels")
    tree = clean_copy(os.path.join(tmp, "tree-wheel"))
    build, done = timed([sys.executable, "-m", "pip", "wheel", tree, "--no-deps", "-w", wheels])
    if done.returncode:
        sys.exit(f"error: pip wheel failed:\n{done.stderr}")
    (wheel,) = glob.glob(os.path.join(wheels, "*.whl"))
    wheel_bin = fresh_venv(os.path.join(tmp, "wheel-venv"))
    install, done = timed(
        [os.path.join(wheel_bin, "pip"), "install", wheel], env=no_compiler_env(tmp)
    )
    if done.returncode:
        sys.exit(f"error: installing the wheel failed (without a compiler):\n{done.stderr}")
    source_bin = fresh_venv(os.path.join(tmp, "source-venv"))
    tree = clean_copy(os.path.join(tmp, "tree-source"))
    source, done = timed([os.path.join(source_bin, "pip"), "install", tree])
    if done.returncode:
        sys.exit(f"error: pip install . failed:\n{done.stderr}")
    run, report = sample(wheel_bin)
    if report != sample(source_bin)[1]:
        sys.exit("error: the wheel's and the source install's reports differ")
    times = {"build": build, "wheel": install, "run": run, "source": source}
    print(
        f"  {os.path.basename(wheel)}: "
        + ", ".join(f"{k} {w:.1f} s wall, {c:.1f} s CPU" for k, (w, c) in times.items()),
        flush=True,
    )
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    rounds = []
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            rounds.append(one_round(tmp))
    rows = {
        "pip wheel . --no-deps (compiles)": "build",
        "pip install WHEEL, fresh venv, no compiler": "wheel",
        "meshcheck sample_meshes/*.stl, first run": "run",
        "pip install ., fresh venv (compiles)": "source",
    }
    print(f"\nmedians of {args.rounds} rounds (the sample's reports were identical)")
    print(f"{'':<44}{'wall s':>8}{'CPU s':>8}")
    for label, k in rows.items():
        wall, cpu = (statistics.median(r[k][i] for r in rounds) for i in (0, 1))
        print(f"{label:<44}{wall:>8.1f}{cpu:>8.1f}")
    wall, cpu = (statistics.median(r["wheel"][i] / r["source"][i] for r in rounds) for i in (0, 1))
    print(f"{'wheel install / source install, per round':<44}{wall:>7.2f}x{cpu:>7.2f}x")


if __name__ == "__main__":
    main()
