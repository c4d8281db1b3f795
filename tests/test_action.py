"""The GitHub Action's steps, run locally: scripts/action/meshcheck_action.py with the variables
GitHub would set pointing at ordinary files, and the real meshcheck on the sample's meshes.

What cannot run here (actions/cache, upload-artifact, codeql's SARIF upload) is checked as
configuration: action.yml and the workflows validate against the schemas check-jsonschema ships,
and every shell step of action.yml is one call of the script tested here.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "action" / "meshcheck_action.py"
SAMPLE = ROOT / "sample_meshes"

sys.path.insert(0, str(SCRIPT.parent))
import meshcheck_action as action  # noqa: E402


def outputs(path: Path) -> dict[str, str]:
    return dict(line.split("=", 1) for line in path.read_text().splitlines())


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    """A checkout whose part files have spaces in their names, and GitHub's files for a step."""
    (tmp_path / "my parts").mkdir()
    shutil.copy(SAMPLE / "plate.stl", tmp_path / "my parts" / "plate 1.stl")
    shutil.copy(SAMPLE / "bolt_m8_oversized.stl", tmp_path / "my parts" / "bolt m8.stl")
    shutil.copy(SAMPLE / "bracket.stl", tmp_path / "bracket.stl")
    github = tmp_path.parent / f"{tmp_path.name}-github"
    github.mkdir()
    env = {
        **os.environ,
        # the meshcheck of this test run, first on PATH as after the install step
        "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]]),
        "GITHUB_OUTPUT": str(github / "output"),
        "GITHUB_STEP_SUMMARY": str(github / "summary.md"),
        "RUNNER_OS": "Linux",
        "FILES": "my parts/plate 1.stl\nmy parts/bolt m8.stl\n\nbracket.stl\n",
        "ARGS": "",
        "CACHE_DIR": ".meshcheck-cache",
        "REPORT_DIR": "meshcheck reports",
        "ARTIFACT_NAME": "assembly",
    }
    env.pop("FORK_PULL_REQUEST", None)
    (github / "output").touch()
    (github / "summary.md").touch()
    return tmp_path, github, env


def step(name: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), name],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def cache_files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


# -------------------------------------------------------------------------------------------
# the files input


def test_files_one_per_line_keeps_spaces():
    files = "my parts/plate 1.stl\n  bolts/  \n\nbracket.stl\n"
    assert action.input_paths(files) == ["my parts/plate 1.stl", "bolts/", "bracket.stl"]


def test_one_line_is_split_on_spaces_unless_it_is_a_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert action.input_paths("plate.stl  bolts/") == ["plate.stl", "bolts/"]
    (tmp_path / "plate 1.stl").touch()
    assert action.input_paths("plate 1.stl") == ["plate 1.stl"]


# -------------------------------------------------------------------------------------------
# the check step, end to end


@pytest.mark.slow
def test_check_step_on_files_with_spaces(workspace):
    cwd, github, env = workspace
    done = step("check", cwd, env)
    assert done.returncode == 0, done.stderr  # the verdict fails the job later, in "fail"
    assert outputs(github / "output")["exit-code"] == "1"
    assert "::error file=my parts/bolt m8.stl," in done.stdout
    reports = cwd / "meshcheck reports"
    assert sorted(p.name for p in reports.iterdir()) == sorted(
        [*action.REPORTS.values(), action.EXPORT]
    )
    parts = {f["a"] for f in json.loads((reports / "meshcheck.json").read_text())["results"]}
    assert parts == {"my parts/bolt m8.stl", "bracket.stl"}
    assert (reports / "meshcheck.glb").read_bytes()[:4] == b"glTF"
    assert "interference" in (github / "summary.md").read_text()
    assert step("fail", cwd, {**env, "STATUS": "1"}).returncode == 1


@pytest.mark.slow
def test_fork_pull_request_without_secret_degrades(workspace):
    cwd, github, env = workspace
    env = {**env, "FORK_PULL_REQUEST": "true", "UPLOAD_SARIF": "true"}
    env.pop("MESHCHECK_CACHE_SECRET", None)
    done = step("check", cwd, env)
    assert done.returncode == 0, done.stderr
    assert re.search(
        r"::notice title=meshcheck::MESHCHECK_CACHE_SECRET is not set \(a pull "
        r"request from a fork",
        done.stdout,
    )
    assert outputs(github / "output")["exit-code"] == "1"
    assert step("summary", cwd, env).returncode == 0
    summary = (github / "summary.md").read_text()
    assert "SARIF not uploaded to code scanning" in summary
    # the reports are all there for the artifact, and the job fails on the verdict alone
    assert (cwd / "meshcheck reports" / "meshcheck.html").is_file()
    assert step("fail", cwd, {**env, "STATUS": "1"}).returncode == 1


def test_summary_links_the_artifact_and_names_html_and_glb(workspace):
    cwd, github, env = workspace
    reports = cwd / "meshcheck reports"
    reports.mkdir()
    for name in ("meshcheck.html", "meshcheck.glb", "meshcheck.json"):
        (reports / name).write_text("x")
    url = "https://github.com/o/r/actions/runs/1/artifacts/2"
    assert step("summary", cwd, {**env, "ARTIFACT_URL": url}).returncode == 0
    summary = (github / "summary.md").read_text()
    assert f"[assembly]({url}) (meshcheck.html, meshcheck.glb, meshcheck.json)" in summary
    assert "SARIF" not in summary  # not asked for, not a fork


def test_summary_without_an_upload_says_where_the_reports_are(workspace):
    cwd, github, env = workspace
    (cwd / "meshcheck reports").mkdir()
    (cwd / "meshcheck reports" / "meshcheck.html").write_text("x")
    assert step("summary", cwd, env).returncode == 0
    assert "Reports in `meshcheck reports`" in (github / "summary.md").read_text()


@pytest.mark.parametrize(("status", "code"), [("0", 0), ("1", 1), ("3", 3), ("", 4)])
def test_fail_step_exits_with_meshchecks_status(workspace, status, code):
    cwd, _, env = workspace
    assert step("fail", cwd, {**env, "STATUS": status}).returncode == code


# -------------------------------------------------------------------------------------------
# the cache: keyed by content, pruned to what the last run used


def test_key_follows_the_inputs_content(workspace):
    cwd, github, env = workspace
    keys = []
    for change in (None, None, "bracket.stl", "ARTIFACT_NAME"):
        if change == "bracket.stl":
            with open(cwd / "bracket.stl", "ab") as f:
                f.write(b"\0")
        run_env = {**env, "ARTIFACT_NAME": "other"} if change == "ARTIFACT_NAME" else env
        assert step("key", cwd, run_env).returncode == 0
        keys.append((outputs(github / "output")["prefix"], outputs(github / "output")["key"]))
    assert keys[0] == keys[1]  # same content: same entry, nothing new saved
    assert keys[2][0] == keys[0][0] and keys[2][1] != keys[0][1]  # restores the newest by prefix
    assert keys[3][0] == "meshcheck-Linux-other-"  # a second use of the action keeps its own
    assert all(key.startswith(prefix) for prefix, key in keys)


@pytest.mark.slow
def test_cache_is_pruned_to_the_entries_the_run_used(workspace):
    cwd, _, env = workspace
    # CoACD runs on the sample's small parts only when forced (the cost model says it never pays
    # there): the pruning must keep the decompositions a run used.
    env = {**env, "MESHCHECK_COACD_BUDGET": "300"}
    cache = cwd / ".meshcheck-cache"
    if not action.atime_works(str(cwd)):
        pytest.skip("this filesystem does not update access times (noatime)")
    assert step("check", cwd, env).returncode == 0
    used = cache_files(cache)
    assert any(name.startswith("decompositions") for name in used)
    # entries of parts that are gone: a decomposition, a verdict, a whole old folder
    entry = next(p for p in cache.rglob("*.bin"))
    shutil.copy(entry, entry.with_name("0" * 64 + ".bin"))
    (cache / "pairs-v1").mkdir()
    (cache / "pairs-v1" / "old.json").write_text("{}")
    assert step("check", cwd, env).returncode == 0
    assert cache_files(cache) == used
    assert not (cache / "pairs-v1").exists()


@pytest.mark.slow
def test_cache_is_not_pruned_after_a_run_that_did_not_complete(workspace):
    cwd, github, env = workspace
    assert step("check", cwd, env).returncode == 0
    before = cache_files(cwd / ".meshcheck-cache")
    # exit 2 (a usage error): meshcheck read no entry, and none may go
    assert step("check", cwd, {**env, "ARGS": "--clearance nonsense"}).returncode == 0
    assert outputs(github / "output")["exit-code"] == "2"
    assert cache_files(cwd / ".meshcheck-cache") == before


def test_args_are_split_as_a_shell_would(monkeypatch, tmp_path):
    monkeypatch.setenv("ARGS", "--clearance 0.5 --config 'my config.toml'")
    monkeypatch.setenv("BASELINE", "")
    command = action.meshcheck_command(["a b.stl"], str(tmp_path), ".cache")
    assert command[:7] == [
        "meshcheck",
        "a b.stl",
        "--clearance",
        "0.5",
        "--config",
        "my config.toml",
        "--cache-dir",
    ]
    assert command[-2:] == ["--export", str(tmp_path / "meshcheck.glb")]


# -------------------------------------------------------------------------------------------
# install


def test_install_uses_the_wheel_only_at_the_release_tag(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\nversion = "1.2.3"\n')
    pip = [sys.executable, "-m", "pip", "install", "--quiet"]
    source = [*pip, str(tmp_path)]
    wheel = [*pip, "--only-binary", "meshcheck-assembly", "meshcheck-assembly==1.2.3"]
    assert action.install_commands("", str(tmp_path), "v1.2.3") == [wheel, source]
    assert action.install_commands("", str(tmp_path), "main") == [source]
    assert action.install_commands("", str(tmp_path), "") == [source]  # uses: ./
    assert action.install_commands("meshcheck-assembly[dask]", str(tmp_path), "v1.2.3") == [
        [*pip, "meshcheck-assembly[dask]"]
    ]


def test_action_installs_the_distribution_this_repository_builds():
    import tomllib

    import meshcheck

    with open(ROOT / "pyproject.toml", "rb") as f:
        assert tomllib.load(f)["project"]["name"] == action.DISTRIBUTION == meshcheck.DISTRIBUTION


# -------------------------------------------------------------------------------------------
# configuration that only GitHub runs


def test_every_shell_step_of_the_action_is_one_call_of_the_script():
    steps = yaml.safe_load((ROOT / "action.yml").read_text())["runs"]["steps"]
    calls = [s["run"] for s in steps if "run" in s]
    pattern = r'python "\$GITHUB_ACTION_PATH/scripts/action/meshcheck_action.py" (\w+)'
    names = [re.fullmatch(pattern, call.strip()) for call in calls]
    assert all(names), calls
    assert [m[1] for m in names] == ["install", "key", "check", "summary", "fail"]


def test_two_uses_in_one_workflow_do_not_share_an_artifact_name():
    action_yml = yaml.safe_load((ROOT / "action.yml").read_text())
    upload = next(s for s in action_yml["runs"]["steps"] if s.get("id") == "upload")
    assert upload["with"]["name"] == "${{ inputs.artifact-name }}"
    workflow = yaml.safe_load((ROOT / ".github" / "workflows" / "action.yml").read_text())
    names = [
        s["with"]["artifact-name"]
        for job in workflow["jobs"].values()
        for s in job["steps"]
        if s.get("uses") == "./"
    ]
    assert len(names) >= 2 and len(set(names)) == len(names)


@pytest.mark.parametrize(
    ("path", "schema"),
    [("action.yml", "vendor.github-actions")]
    + [
        (f".github/workflows/{p.name}", "vendor.github-workflows")
        for p in sorted((ROOT / ".github" / "workflows").glob("*.yml"))
    ],
)
def test_github_configuration_is_valid(path, schema):
    done = subprocess.run(
        [sys.executable, "-m", "check_jsonschema", "--builtin-schema", schema, str(ROOT / path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
