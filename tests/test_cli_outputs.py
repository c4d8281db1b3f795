"""Outputs from the command line: every report from one run, paths checked before any work,
nothing but regular files replaced, write failures and bugs with their own status, baselines."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pytest
import trimesh
from click.testing import CliRunner

from meshcheck.cli import main
from meshcheck.errors import ConfigError, ExitStatus, OutputError
from meshcheck.output import check_output, write_output

ROOT = Path(__file__).resolve().parents[1]


def run(args, **kwargs):
    """Invoke the command; no traceback, and no exception but SystemExit."""
    result = CliRunner().invoke(main, [str(a) for a in args], **kwargs)
    assert "Traceback" not in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result


@pytest.fixture
def clash(tmp_path):
    """Two unit boxes overlapping by 0.5: one interference."""
    paths = []
    for name, x in (("a.stl", 0.0), ("b.stl", 0.5)):
        path = tmp_path / name
        trimesh.creation.box(extents=(1, 1, 1)).apply_translation((x, 0, 0)).export(str(path))
        paths.append(str(path))
    return paths


@pytest.fixture
def no_check(monkeypatch):
    """Make the check itself a failure, to prove a refusal comes before any work."""

    def refuse(*args, **kwargs):
        raise AssertionError("the check ran")

    monkeypatch.setattr("meshcheck.pipeline.check", refuse)


def one_error_line(result, *fragments):
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


# ------------------------------------------------------------------------------------------
# Paths checked before any work: exit 2, one line


@pytest.mark.posix_only
@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["-o", "/nonexistent-dir/r.txt"], "does not exist"),
        (["--report", "junit:/nonexistent-dir/r.xml"], "does not exist"),
        (["--export", "/nonexistent-dir/x.glb"], "does not exist"),
        (["--export", "{tmp}/x.obj"], ".glb or .gltf"),
        (["-o", "{tmp}"], "it is a directory"),
        (["--report", "sarif:{tmp}/fifo"], "it is a FIFO"),
        (["--report", "json:-", "--format", "text"], "two reports would be written to standard"),
        (["--report", "json:{tmp}/r", "--report", "junit:{tmp}/r"], "two reports would be"),
        (["--baseline", "{tmp}/missing.json"], "cannot read the baseline"),
        (["--baseline", "{tmp}/fifo"], "regular file"),
        (["--report", "json:{tmp}/a.stl"], "is an input"),
    ],
)
def test_outputs_are_checked_before_any_work(tmp_path, clash, no_check, args, fragment):
    os.mkfifo(tmp_path / "fifo")
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    result = run([*clash, "--no-cache", "--no-config", *args])
    assert result.exit_code == ExitStatus.USAGE
    one_error_line(result, fragment)
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)


@pytest.mark.parametrize("spec", ["junit", "junit:", "yaml:r.txt", ":r.txt"])
def test_a_bad_report_option_is_a_usage_error(clash, no_check, spec):
    result = run([*clash, "--report", spec])
    assert result.exit_code == ExitStatus.USAGE
    assert "--report" in result.stderr


@pytest.mark.posix_only
def test_check_output_rules(tmp_path):
    check_output(str(tmp_path / "new.txt"))
    (tmp_path / "old.txt").write_text("x")
    check_output(str(tmp_path / "old.txt"))
    check_output(os.devnull)
    check_output("-")
    os.symlink(tmp_path / "nowhere", tmp_path / "dangling")
    with pytest.raises(ConfigError, match="dangling"):
        check_output(str(tmp_path / "dangling"))
    with pytest.raises(ConfigError, match="a directory"):
        check_output(str(tmp_path))


# ------------------------------------------------------------------------------------------
# Writing: atomic for files, in place for devices, never a rename over a non-file


@pytest.mark.linux_only
def test_a_device_is_written_to_never_replaced(tmp_path):
    write_output(os.devnull, "report\n")
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)
    with pytest.raises(OutputError, match="/dev/full: cannot write the report"):
        write_output("/dev/full", "report\n")
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


@pytest.mark.posix_only
def test_files_are_replaced_atomically_keeping_their_mode(tmp_path):
    path = tmp_path / "r.txt"
    path.write_text("old")
    path.chmod(0o640)
    write_output(str(path), "new")
    assert path.read_text() == "new"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["r.txt"]  # no temporary left
    link = tmp_path / "link.txt"
    link.symlink_to(path)
    write_output(str(link), "through")
    assert link.is_symlink() and path.read_text() == "through"


def test_every_report_from_one_run(tmp_path, clash):
    out = {name: tmp_path / name for name in ("r.xml", "r.sarif", "summary.md", "r.json")}
    result = run(
        [
            *clash,
            "--no-cache",
            "--no-config",
            "--report",
            f"junit:{out['r.xml']}",
            "--report",
            f"sarif:{out['r.sarif']}",
            "--report",
            f"markdown:{out['summary.md']}",
            "--report",
            f"json:{out['r.json']}",
            "--report",
            "github:-",
        ]
    )
    assert result.exit_code == ExitStatus.FAILED, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("::error file=") and lines[-1].startswith("FAIL: 2 parts")
    assert ElementTree.parse(out["r.xml"]).getroot().get("failures") == "1"
    sarif = json.loads(out["r.sarif"].read_text())
    assert sarif["runs"][0]["results"][0]["level"] == "error"
    assert out["summary.md"].read_text().startswith("## ❌ meshcheck: FAIL")
    assert json.loads(out["r.json"].read_text())["summary"]["interference"] == 1


def test_reports_only_to_files_put_the_summary_on_stderr(tmp_path, clash):
    report, text = tmp_path / "r.xml", tmp_path / "r.txt"
    result = run([*clash, "--no-cache", "--no-config", "--report", f"junit:{report}"])
    assert result.stdout.splitlines()[-1].startswith("FAIL: 2 parts")  # --format still on stdout
    result = run([*clash, "--no-cache", "--no-config", "--report", f"junit:{report}", "-o", text])
    assert result.exit_code == ExitStatus.FAILED
    assert result.stdout == ""
    assert result.stderr.startswith("FAIL: 2 parts")
    assert f"reports written to {text}, {report}" in result.stderr
    assert text.read_text().splitlines()[-1].startswith("FAIL: 2 parts")


@pytest.mark.linux_only
def test_a_report_to_a_full_device_is_one_line_and_exit_5(clash):
    result = run([*clash, "--no-cache", "--no-config", "--report", "junit:/dev/full"])
    assert result.exit_code == ExitStatus.OUTPUT
    assert result.stderr.splitlines() == [
        "error: /dev/full: cannot write the report (No space left on device)"
    ]
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


@pytest.mark.linux_only
def test_stdout_to_a_full_device_is_one_line_and_exit_5(clash):
    with open("/dev/full", "w") as full:
        proc = subprocess.run(
            [sys.executable, "-m", "meshcheck", *clash, "--no-cache", "--no-config"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=300,
            check=False,
            cwd=ROOT,
        )
    assert proc.returncode == ExitStatus.OUTPUT, proc.stderr
    # The contract: progress lines (a slow start on a busy machine) carry the "meshcheck: "
    # prefix, and the error is stderr's last line (tests/test_hostile_inputs_more.py, slow start)
    *progress, last = proc.stderr.splitlines()
    assert last == "error: <stdout>: cannot write the report (No space left on device)"
    assert all(line.startswith("meshcheck: ") for line in progress), progress


def test_export_gltf_writes_gltf_and_glb_writes_glb(tmp_path, clash):
    gltf, glb = tmp_path / "x.gltf", tmp_path / "x.glb"
    for path in (gltf, glb):
        result = run([*clash, "--no-cache", "--no-config", "--export", path])
        assert result.exit_code == ExitStatus.FAILED, result.stderr
    doc = json.loads(gltf.read_text())
    assert doc["asset"]["version"] == "2.0"
    assert all(b["uri"].startswith("data:") for b in doc["buffers"])  # one self-contained file
    assert glb.read_bytes()[:4] == b"glTF"
    assert len(trimesh.load(str(gltf), force="scene").geometry) == 3  # two parts, one clash


# ------------------------------------------------------------------------------------------
# Bugs: their own status, one line, the traceback kept


def test_an_unexpected_error_is_exit_4_with_the_traceback_in_a_file(clash, monkeypatch, tmp_path):
    def broken(*args, **kwargs):
        raise RuntimeError("kaboom\nPASS: forged")

    monkeypatch.setattr("meshcheck.pipeline.check", broken)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.delenv("MESHCHECK_DEBUG", raising=False)
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # read TMPDIR again
    result = run([*clash, "--no-cache", "--no-config"])
    assert result.exit_code == ExitStatus.INTERNAL
    line = one_error_line(result, "internal error", "RuntimeError: kaboom\\nPASS: forged")
    (crash,) = tmp_path.glob("meshcheck-crash-*.txt")
    assert str(crash) in line
    assert "Traceback" in crash.read_text() and "kaboom" in crash.read_text()


def test_meshcheck_debug_prints_the_traceback(clash, monkeypatch):
    monkeypatch.setattr("meshcheck.pipeline.check", lambda *a, **k: 1 / 0)
    monkeypatch.setenv("MESHCHECK_DEBUG", "1")
    result = CliRunner().invoke(main, [*clash, "--no-cache", "--no-config"])
    assert result.exit_code == ExitStatus.INTERNAL
    assert "Traceback" in result.stderr and "ZeroDivisionError" in result.stderr


# ------------------------------------------------------------------------------------------
# Hostile names on the command line


def test_a_forged_file_name_forges_no_line(tmp_path):
    names = ["x\nPASS: 2 parts, 0 interference\n.stl", "y\x1b[2J\x1b]0;t\x07.stl"]
    paths = []
    for name, x in zip(names, (0.0, 0.5), strict=True):
        path = tmp_path / name
        trimesh.creation.box(extents=(1, 1, 1)).apply_translation((x, 0, 0)).export(str(path))
        paths.append(path)
    for fmt in ("text", "github"):
        result = run([*paths, "--no-cache", "--no-config", "--format", fmt])
        assert result.exit_code == ExitStatus.FAILED
        lines = result.stdout.splitlines()
        assert not any(line.startswith("PASS") for line in lines)
        assert all(line.isprintable() for line in lines)
    broken = tmp_path / "z\nPASS: ok\n.stl"
    broken.write_bytes(b"")
    result = run([paths[0], broken, "--no-cache", "--no-config"])
    assert result.exit_code == ExitStatus.INPUT
    one_error_line(result, "z\\nPASS: ok\\n.stl")


# ------------------------------------------------------------------------------------------
# Baselines from the command line


def test_baseline_and_fail_on_new(tmp_path, clash):
    old = tmp_path / "old.json"
    first = run([*clash, "--no-cache", "--no-config", "--report", f"json:{old}"])
    assert first.exit_code == ExitStatus.FAILED
    # the same clash again: active, and --fail-on new lets it pass
    again = run(
        [
            *clash,
            "--no-cache",
            "--no-config",
            "--baseline",
            old,
            "--fail-on",
            "new",
            "--format",
            "json",
        ]
    )
    assert again.exit_code == ExitStatus.OK, again.stderr
    doc = json.loads(again.stdout)
    assert [r["baseline"] for r in doc["results"]] == ["active"]
    assert doc["summary"]["failed"] == 0 and doc["summary"]["fail_on_new"] is True
    # without --fail-on new, a baseline changes no verdict
    plain = run([*clash, "--no-cache", "--no-config", "--baseline", old])
    assert plain.exit_code == ExitStatus.FAILED
    assert "active" in plain.stdout
    # a new clash fails even with --fail-on new
    third = tmp_path / "c.stl"
    trimesh.creation.box(extents=(1, 1, 1)).apply_translation((0, 0.5, 0)).export(str(third))
    new = run([*clash, third, "--no-cache", "--no-config", "--baseline", old, "--fail-on", "new"])
    assert new.exit_code == ExitStatus.FAILED
    assert "2 new, 0 resolved" in new.stdout


def test_a_hostile_baseline_is_one_line_and_exit_2(tmp_path, clash, no_check):
    bad = tmp_path / "bad\n.json"
    bad.write_text("[" * 50_000)
    result = run([*clash, "--baseline", bad])
    assert result.exit_code == ExitStatus.USAGE
    one_error_line(result, "bad\\n.json")


# ------------------------------------------------------------------------------------------
# Packaged for CI: the action's command line is one this meshcheck accepts


def test_the_action_runs_options_that_exist_and_saves_the_cache_always():
    import sys

    from meshcheck.reports import FORMATS

    sys.path.insert(0, str(ROOT / "scripts" / "action"))
    import meshcheck_action

    assert set(meshcheck_action.REPORTS) <= set(FORMATS)
    known = {opt for param in main.params for opt in param.opts}
    command = meshcheck_action.meshcheck_command(["a.stl"], "reports", ".cache")
    for option in (arg for arg in command if arg.startswith("--")):
        assert option in known, option
    action = (ROOT / "action.yml").read_text()
    save = action.index("uses: actions/cache/save@")
    assert "if: always()" in action[action.rindex("- name:", 0, save) : save]
    assert "uses: actions/cache/restore@" in action
    hooks = (ROOT / ".pre-commit-hooks.yaml").read_text()
    assert "entry: meshcheck" in hooks and "pass_filenames: false" in hooks
