"""The command line through CliRunner: stdout, stderr, exit status, and never a traceback."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree

import pytest
import trimesh
from click.testing import CliRunner
from meshes import box

from meshcheck.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "sample_meshes").glob("*.stl"))
OVERSIZED = "sample_meshes/bolt_m8_oversized.stl"
PLATE = "sample_meshes/plate.stl"


def run(args, **kwargs):
    """Invoke the command; check the invariants every run must keep."""
    result = CliRunner().invoke(main, [str(a) for a in args], **kwargs)
    assert "Traceback" not in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory):
    """One decomposition cache for the module, so CoACD runs once per part."""
    return str(tmp_path_factory.mktemp("cache"))


@pytest.fixture
def in_root(monkeypatch):
    monkeypatch.chdir(ROOT)


# ------------------------------------------------------------------------------------------
# Usage, broken inputs, configuration errors: no geometry needed


def test_python_m_meshcheck_help():
    proc = subprocess.run(
        [sys.executable, "-m", "meshcheck", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("Usage: meshcheck [OPTIONS] FILES...")
    for option in (
        "--format",
        "--clearance",
        "--tolerance",
        "--threshold",
        "--cache-dir",
        "--no-cache",
        "--output",
        "--fail-on",
        "--split",
        "--config",
    ):
        assert option in proc.stdout


def test_no_files_is_a_usage_error():
    result = run([])
    assert result.exit_code == 2
    assert "Missing argument" in result.stderr


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("--format", "yaml"),
        ("--fail-on", "interference,overlap"),
        ("--fail-on", "none,touching"),
        ("--clearance", "-1"),
        ("--clearance", "nan"),
        ("--clearance", "inf"),
        ("--tolerance", "nan"),
        ("--tolerance", "inf"),
        ("--tolerance", "-0.1"),
        ("--threshold", "nan"),
        ("--threshold", "2"),
        ("--jobs", "0"),
    ],
)
def test_bad_option_is_a_usage_error(tmp_path, option, value):
    result = run([option, value, tmp_path / "a.stl"])
    assert result.exit_code == 2
    assert result.stdout == ""


BROKEN = {
    "missing.stl": (None, "no such file or directory"),
    "empty.stl": (b"", "empty file"),
    "truncated.stl": (b"\0" * 80 + (12).to_bytes(4, "little") + b"\0" * 500, "truncated"),
    "huge.stl": (b"\0" * 80 + (4_000_000_000).to_bytes(4, "little") + b"\0" * 100, "4000000000"),
    "garbage.stl": (bytes(range(256)) * 5, "binary STL"),
    "cloud.ply": (
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
        "point cloud",
    ),
    "nan.obj": (b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "NaN or infinite"),
    "inf.obj": (b"v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n", "NaN or infinite"),
    "part.step": (b"ISO-10303-21;\n", "cannot be read as STEP: Line 3: Incorrect syntax"),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_input_is_one_error_line_and_exit_3(tmp_path, name):
    content, reason = BROKEN[name]
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    good = tmp_path / "good.stl"
    box(at=(5, 0, 0)).export(str(good))
    result = run([good, path, "--no-cache"])
    assert result.exit_code == 3
    assert result.stdout == ""
    # Without a terminal, a stage still busy after 2 s says so (importing OpenCASCADE may
    # take that long on a loaded machine): those lines start with "meshcheck: ".
    lines = [line for line in result.stderr.splitlines() if not line.startswith("meshcheck: ")]
    assert len(lines) == 1 and result.stderr.splitlines()[-1] == lines[0]
    assert lines[0].startswith(f"error: {path}: ")
    assert reason in lines[0]


def test_directory_without_meshes_is_exit_3(tmp_path):
    (tmp_path / "notes.txt").write_text("no meshes here")
    result = run([tmp_path, "--no-cache"])
    assert result.exit_code == 3
    assert result.stderr.startswith(f"error: {tmp_path}: directory holds no mesh files")


def test_warnings_are_one_line_each_before_the_error(tmp_path):
    cube = box()
    open_mesh = tmp_path / "open.stl"
    trimesh.Trimesh(cube.vertices, cube.faces[:-2], process=False).export(str(open_mesh))
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    result = run([open_mesh, empty, "--no-cache"])
    assert result.exit_code == 3
    assert result.stderr.splitlines() == [
        f"warning: {open_mesh}: mesh is not closed (not watertight); "
        "its findings rest on surfaces only",
        f"error: {empty}: empty file",
    ]


def test_invalid_config_is_exit_2_naming_the_file(tmp_path, monkeypatch):
    (tmp_path / "meshcheck.toml").write_text('[[ignore]]\na = "x"\nb = "y"\n')
    monkeypatch.chdir(tmp_path)
    result = run(["a.stl"])
    assert result.exit_code == 2
    config = tmp_path / "meshcheck.toml"
    assert (
        result.stderr == f"error: {config}: ignore entry 1 has no 'reason': "
        "say why the finding is approved\n"
    )


def test_explicit_config_file_that_is_missing_is_exit_2(tmp_path):
    result = run(["--config", tmp_path / "nope.toml", "a.stl"])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error: {tmp_path / 'nope.toml'}: cannot be read")


# ------------------------------------------------------------------------------------------
# Whole runs on the sample assembly (the full pipeline)


@pytest.fixture(scope="module")
def sample_json(cache_dir):
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        result = run([*SAMPLES, "--format", "json", "--cache-dir", cache_dir, "--no-config"])
    finally:
        os.chdir(cwd)
    return result


def test_sample_assembly_fails_on_the_oversized_bolt(sample_json):
    assert sample_json.exit_code == 1, sample_json.stderr
    doc = json.loads(sample_json.stdout)
    assert set(doc) == {"results", "groups", "parts", "summary"}
    assert [p["name"] for p in doc["parts"]] == SAMPLES
    clashes = [r for r in doc["results"] if r["status"] == "interference"]
    assert [(r["a"], r["b"]) for r in clashes] == [(OVERSIZED, PLATE)]
    (clash,) = clashes
    assert clash["distance"] == 0
    assert clash["depth"] > 0 and clash["volume"] > 0
    assert len(clash["id"]) == 12
    for r in doc["results"]:
        assert {"a", "b", "status", "distance", "depth", "volume", "id"} <= set(r)
        assert r["a"] < r["b"]
        assert r["status"] in ("interference", "touching", "clearance")
    assert doc["summary"]["interference"] == 1
    assert doc["summary"]["passed"] is False


def test_sample_text_report(in_root, cache_dir):
    result = run([*SAMPLES, "--cache-dir", cache_dir, "--no-config"])
    assert result.exit_code == 1
    lines = result.stdout.splitlines()
    assert lines[0] == "parts below sample_meshes/"  # the shared prefix, named once
    assert any("interference" in line and "  bolt_m8_oversized.stl" in line for line in lines)
    assert all(len(line) <= 100 for line in lines)
    assert lines[-1].startswith("FAIL: 6 parts, 1 interference")


def test_sample_without_the_oversized_bolt_passes(in_root, cache_dir):
    parts = [p for p in SAMPLES if p != OVERSIZED]
    result = run([*parts, "--cache-dir", cache_dir, "--no-config"])
    assert result.exit_code == 0, result.stdout + result.stderr
    assert result.stdout.splitlines()[-1].startswith("PASS: 5 parts, 0 interference")


def test_directory_argument_matches_the_file_list(tmp_path, monkeypatch, cache_dir, sample_json):
    # the STL files alone (sample_meshes/ also holds the same assembly as one STEP file)
    (tmp_path / "sample_meshes").mkdir()
    for p in SAMPLES:
        shutil.copy(ROOT / p, tmp_path / p)
    monkeypatch.chdir(tmp_path)
    result = run(["sample_meshes", "--format", "json", "--cache-dir", cache_dir, "--no-config"])
    assert result.exit_code == 1
    doc = json.loads(result.stdout)
    assert [p["name"] for p in doc["parts"]] == [
        os.path.join("sample_meshes", Path(p).name) for p in SAMPLES
    ]
    assert doc["results"] == json.loads(sample_json.stdout)["results"]


def test_fail_on_touching_fails_the_clean_assembly(in_root, cache_dir):
    parts = [p for p in SAMPLES if p != OVERSIZED]
    result = run([*parts, "--cache-dir", cache_dir, "--no-config", "--fail-on", "touching"])
    assert result.exit_code == 1
    assert result.stdout.splitlines()[-1].startswith("FAIL")
    none = run([*SAMPLES, "--cache-dir", cache_dir, "--no-config", "--fail-on", "none"])
    assert none.exit_code == 0


def test_approved_interference_passes(tmp_path, monkeypatch, cache_dir):
    (tmp_path / "meshcheck.toml").write_text(
        '[[ignore]]\na = "*plate.stl"\nb = "*bolt_m8_*"\nreason = "bolt to be reamed"\n'
    )
    monkeypatch.chdir(tmp_path)
    files = [str(ROOT / p) for p in SAMPLES]
    result = run([*files, "--cache-dir", cache_dir])
    assert result.exit_code == 0, result.stdout + result.stderr
    assert "approved" in result.stdout
    assert "bolt to be reamed" in " ".join(result.stdout.split())  # the detail may wrap
    junit = run([*files, "--cache-dir", cache_dir, "--format", "junit"])
    root = ElementTree.fromstring(junit.stdout)
    assert (root.get("failures"), root.get("skipped")) == ("0", "1")
    # the command line wins over the file
    strict = run([*files, "--cache-dir", cache_dir, "--no-config"])
    assert strict.exit_code == 1


def test_groups_restrict_the_pairs(tmp_path, monkeypatch, cache_dir):
    config = tmp_path / "pyproject.toml"
    config.write_text('[tool.meshcheck.groups]\na = ["*bracket.stl"]\nb = ["*plate.stl"]\n')
    files = [str(ROOT / p) for p in SAMPLES]
    result = run([*files, "--cache-dir", cache_dir, "--config", config, "--format", "json"])
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert [(Path(r["a"]).name, Path(r["b"]).name) for r in doc["results"]] == [
        ("bracket.stl", "plate.stl"),
    ]


def test_junit_report(in_root, cache_dir):
    result = run([*SAMPLES, "--cache-dir", cache_dir, "--no-config", "--format", "junit"])
    assert result.exit_code == 1
    root = ElementTree.fromstring(result.stdout)
    suite = root.find("testsuite")
    cases = suite.findall("testcase")
    failures = [c for c in cases if c.find("failure") is not None]
    assert len(failures) == 1
    assert OVERSIZED in failures[0].get("name") and PLATE in failures[0].get("name")
    assert suite.get("failures") == "1"
    assert suite.get("tests") == str(len(cases))


def test_github_report(in_root, cache_dir):
    result = run([*SAMPLES, "--cache-dir", cache_dir, "--no-config", "--format", "github"])
    assert result.exit_code == 1
    errors = [line for line in result.stdout.splitlines() if line.startswith("::error ")]
    assert len(errors) == 1
    assert errors[0].startswith(f"::error file={OVERSIZED},title=meshcheck interference [")
    assert all(
        line.startswith(("::warning ", "::notice ", "::error ", "FAIL", "PASS"))
        for line in result.stdout.splitlines()
    )


def test_output_file(in_root, cache_dir, tmp_path):
    out = tmp_path / "report.json"
    result = run(
        [*SAMPLES, "--cache-dir", cache_dir, "--no-config", "--format", "json", "--output", out]
    )
    assert result.exit_code == 1
    assert result.stdout == ""
    assert f"report written to {out}" in result.stderr
    assert json.loads(out.read_text())["summary"]["interference"] == 1


def test_clearance_violation_fails(in_root, cache_dir):
    # the bracket stands 10.83 mm from bolt C
    args = [
        "sample_meshes/bolt_m6_c.stl",
        "sample_meshes/bracket.stl",
        "--cache-dir",
        cache_dir,
        "--no-config",
        "--format",
        "json",
    ]
    near = run([*args, "--clearance", "11"])
    assert near.exit_code == 1
    doc = json.loads(near.stdout)
    (finding,) = doc["results"]
    assert finding["status"] == "clearance"
    assert finding["distance"] == pytest.approx(10.83, abs=0.01)
    assert (doc["summary"]["clearance"], doc["summary"]["required_clearance"]) == (1, 11.0)
    assert run([*args, "--clearance", "10"]).exit_code == 0
    # --fail-on adds to the default: a clearance that is set still fails the run
    assert run([*args, "--clearance", "11", "--fail-on", "interference"]).exit_code == 1
    assert run([*args, "--clearance", "11", "--fail-on", "none"]).exit_code == 0


# ------------------------------------------------------------------------------------------
# Multi-body files and --split through the command line


def test_multi_body_glb_names_parts_by_node(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(box((2, 2, 2)), node_name="housing", geom_name="housing")
    scene.add_geometry(box(at=(1.2, 0, 0)), node_name="pin", geom_name="pin")
    scene.add_geometry(box(at=(5, 0, 0)), node_name="far", geom_name="far")
    path = tmp_path / "assy.glb"
    scene.export(str(path))
    result = run([path, "--no-cache", "--no-config", "--format", "json"])
    assert result.exit_code == 1, result.stderr
    doc = json.loads(result.stdout)
    assert [p["name"] for p in doc["parts"]] == [f"{path}#far", f"{path}#housing", f"{path}#pin"]
    assert [(r["a"], r["b"], r["status"]) for r in doc["results"]] == [
        (f"{path}#housing", f"{path}#pin", "interference"),
    ]
    assert doc["results"][0]["depth"] == pytest.approx(0.3, abs=1e-6)


def test_split_checks_shells_against_each_other(tmp_path):
    path = tmp_path / "shells.stl"
    trimesh.util.concatenate([box(at=(0, 0, 0)), box(at=(0.5, 0, 0))]).export(str(path))
    whole = run([path, "--no-cache", "--no-config"])
    assert whole.exit_code == 0, whole.stderr  # one part cannot clash with itself
    split = run([path, "--no-cache", "--no-config", "--split", "--format", "json"])
    assert split.exit_code == 1, split.stderr
    doc = json.loads(split.stdout)
    assert [(r["a"], r["b"], r["status"]) for r in doc["results"]] == [
        (f"{path}#1", f"{path}#2", "interference"),
    ]


@pytest.mark.posix_only  # os.kill(SIGINT) ends a process on Windows
def test_a_ctrl_c_during_an_import_that_catches_everything_still_ends_the_run():
    """trimesh imports its optional modules under ``except BaseException``: a Ctrl-C raised
    there would be swallowed and the run go on. While the pipeline is imported it is noted,
    and raised once the import is over."""
    import signal

    from meshcheck.cli import _interrupts_held

    swallowed = []
    with pytest.raises(KeyboardInterrupt), _interrupts_held():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler runs between two bytecodes
        except BaseException as exc:  # an optional import's guard
            swallowed.append(exc)
    assert swallowed == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


@pytest.mark.posix_only  # os.kill(SIGINT) ends a process on Windows
def test_an_error_after_a_ctrl_c_a_library_swallowed_is_an_interruption(monkeypatch):
    """A Ctrl-C met in an import under ``except BaseException`` (trimesh's optional modules)
    is swallowed there, and the half-made module fails later: exit 130, not a bug."""
    import signal

    from meshcheck import pipeline

    def check(files, settings):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler runs between two bytecodes
        except BaseException:  # an optional import's guard
            pass
        raise ImportError("no graph engines available!")

    monkeypatch.setattr(pipeline, "check", check)
    result = run([PLATE])
    assert (result.exit_code, result.stderr) == (130, "error: interrupted\n")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_error_a_ctrl_c_caused_is_an_interruption_not_a_bug():
    from meshcheck.cli import _is_interrupt

    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:  # what pybind11 does in an extension's initialisation
            raise ImportError("initialization failed") from exc
    except ImportError as exc:
        assert _is_interrupt(exc)
    assert not _is_interrupt(ImportError("initialization failed"))
    looped = ValueError("a")
    looped.__context__ = ValueError("b")
    looped.__context__.__context__ = looped
    assert not _is_interrupt(looped)
