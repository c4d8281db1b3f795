"""A report is a function of the inputs and options only: cold or warm, -j 1 or -j 2,
CoACD finished or cut short, the JSON is the same bytes.

The decompositions here really time out: ``MESHCHECK_COACD_BUDGET`` (a hook for tests and
benchmarks) sends every part to CoACD with a 1 ms limit, and the worker running it is
killed. The runs are whole ``meshcheck`` processes with their own cache directories and key.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLES = ["plate.stl", "bracket.stl", "bolt_m6_a.stl", "bolt_m8_oversized.stl"]


def _run(paths, cache_dir, jobs, env) -> subprocess.CompletedProcess:
    args = [sys.executable, "-m", "meshcheck", "--format", "json", "--no-config"]
    args += ["--cache-dir", str(cache_dir), "-j", str(jobs), *paths]
    return subprocess.run(args, cwd=ROOT, env=env, capture_output=True, timeout=600)


@pytest.fixture
def assembly(tmp_path):
    os.makedirs(tmp_path / "parts")
    paths = []
    for name in SAMPLES:
        shutil.copy(os.path.join(ROOT, "sample_meshes", name), tmp_path / "parts" / name)
        paths.append(str(tmp_path / "parts" / name))
    return paths


def _env(tmp_path, **extra) -> dict:
    env = dict(os.environ, **extra)
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg-cache")
    env["XDG_STATE_HOME"] = str(tmp_path / "xdg-state")
    env["MESHCHECK_CACHE_SECRET"] = "determinism-test"
    env.pop("MESHCHECK_SCHEDULER", None)
    return env


@pytest.mark.slow
def test_json_is_the_same_bytes_cold_warm_any_jobs_with_timed_out_decompositions(
    tmp_path, assembly
):
    timed_out = _env(tmp_path, MESHCHECK_COACD_BUDGET="0.001")
    reports, notes = {}, {}
    for jobs in (1, 2):
        for run, cache in (("cold", "a"), ("warm", "a"), ("cold again", "b")):
            done = _run(assembly, tmp_path / f"cache-{jobs}-{cache}", jobs, timed_out)
            assert done.returncode == 1, done.stderr.decode()[-2000:]  # the oversized bolt
            reports[(jobs, run)] = done.stdout
            notes[(jobs, run)] = done.stderr.decode()
    # The decompositions really were cut short, and said so on stderr (a cold run only: the
    # warm one finds the hulls that stood in, cached).
    for jobs in (1, 2):
        for run in ("cold", "cold again"):
            assert "convex decomposition took over 0.001 s" in notes[(jobs, run)]
    # Without the hook (the cost model decides: no CoACD on four parts), and with the
    # decomposition cache from the timed-out run: the same report.
    plain = _run(assembly, tmp_path / "cache-plain", 1, _env(tmp_path))
    reports[(1, "cost model")] = plain.stdout
    first = reports[(1, "cold")]
    assert b'"interference"' in first and b"took over" not in first
    for key, report in reports.items():
        assert report == first, key


def test_a_sweep_past_its_budget_is_the_same_report_cold_warm_any_jobs(tmp_path):
    """A sweep whose budget runs out in the middle of a link pair: exit 0 (a URDF robot's
    sweep never fails the run), one note on stderr, no traceback; the JSON, text and SRDF
    are the same bytes cold or warm, at -j 1 or -j 2, and with ``MESHCHECK_COACD_BUDGET`` set
    to 1 ms (the sweep's pieces, which the check reuses, take no time limit); the SRDF
    disables as Never only pairs proven so."""
    import json

    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from meshes import chain_urdf

    path = tmp_path / "chain.urdf"
    path.write_text(chain_urdf(6, limit=1.6375))
    outputs, budget = {}, ["--sweep", "--sweep-budget", "30000"]
    for jobs, cache, hook in ((1, "a", None), (1, "a", None), (2, "b", None), (2, "c", "0.001")):
        env = _env(tmp_path) if hook is None else _env(tmp_path, MESHCHECK_COACD_BUDGET=hook)
        for fmt in ("json", "text"):
            srdf = tmp_path / f"{jobs}-{cache}-{fmt}.srdf"
            args = [sys.executable, "-m", "meshcheck", str(path), *budget, "--no-config"]
            args += ["--format", fmt, "--cache-dir", str(tmp_path / cache), "-j", str(jobs)]
            done = subprocess.run(
                [*args, "--srdf", str(srdf)], cwd=ROOT, env=env, capture_output=True, timeout=300
            )
            lines = done.stderr.decode().splitlines()
            assert done.returncode == 0, lines
            assert not any("Traceback" in line for line in lines), lines
            notes = [line for line in lines if "the sweep budget (30,000) ran out" in line]
            assert notes == ["meshcheck: the sweep budget (30,000) ran out: 8 link pairs of "
                             "chain left undecided"], lines  # fmt: skip
            outputs.setdefault(fmt, set()).add(done.stdout)
            outputs.setdefault("srdf", set()).add(srdf.read_bytes())
    assert all(len(found) == 1 for found in outputs.values()), outputs.keys()
    (doc,) = (json.loads(out) for out in outputs["json"])
    (sweep,) = doc["sweeps"]
    assert (sweep["budget"], sweep["unswept"]) == (30_000, 8) and sweep["work"] >= 30_000
    assert sweep["counts"]["undecided"] == 9  # the pair it ran out on, and the eight after it
    never = {(p["a"], p["b"]) for p in sweep["pairs"] if p["status"] == "never"}
    adjacent = {(p["a"], p["b"]) for p in sweep["pairs"] if p["adjacent"]}
    (srdf,) = outputs["srdf"]
    entries = [line.split('"')[1:6:2] for line in srdf.decode().splitlines() if "link1" in line]
    assert {(a, b) for a, b, reason in entries if reason == "Never"} == never - adjacent
    assert {(a, b) for a, b, reason in entries if reason != "Never"} <= adjacent
