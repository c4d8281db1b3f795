"""The pre-commit hook (.pre-commit-hooks.yaml): which changed files make it run.

pre-commit runs a hook when ``re.search(files, path)`` matches a staged path; the hook then
checks the whole assembly named in its ``args``. A file meshcheck reads that the filter misses
is a commit whose clash the hook never sees.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from meshcheck.config import CONFIG_NAMES
from meshcheck.load.files import SUPPORTED_EXTENSIONS

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def hook() -> dict:
    (hook,) = yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())
    return hook


def runs_on(hook: dict, path: str) -> bool:
    return re.search(hook["files"], path) is not None


@pytest.mark.parametrize("ext", SUPPORTED_EXTENSIONS)
def test_every_format_meshcheck_reads_triggers_the_hook(hook, ext):
    assert runs_on(hook, f"assembly/part{ext}")
    assert runs_on(hook, f"assembly/PART{ext.upper()}")


def test_a_commit_changing_only_the_step_file_runs_the_hook(hook):
    assert runs_on(hook, "sample_meshes/assembly.step")
    assert runs_on(hook, "cad/Gearbox.STP")


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_configuration_changes_trigger_the_hook(hook, name):
    assert runs_on(hook, name)
    assert runs_on(hook, f"sub/dir/{name}")


def test_gltf_external_buffers_trigger_the_hook(hook):
    assert runs_on(hook, "assembly/gearbox.bin")


@pytest.mark.parametrize(
    "path", ["README.md", "assembly/notes.step.txt", "other.toml", "mymeshcheck.toml", "a.stlx"]
)
def test_unrelated_files_do_not(hook, path):
    assert not runs_on(hook, path)


def test_the_hook_checks_the_whole_assembly_once(hook):
    assert hook["entry"] == "meshcheck"
    assert hook["pass_filenames"] is False and hook["require_serial"] is True
    assert hook["language"] == "python"


def test_readmes_local_hook_filters_like_the_hook(hook):
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    (files,) = re.findall(r"^ +files: (\(\?i\).+)$", readme, flags=re.MULTILINE)
    assert files == hook["files"]
