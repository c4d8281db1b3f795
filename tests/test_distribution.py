"""meshcheck's distribution name (``meshcheck`` on PyPI is someone else's project) and build.

The command and the import are ``meshcheck``; pip installs ``meshcheck.DISTRIBUTION``. Every place
that names what to install, or reads the installed version, must use that name: a wrong one
installs the unrelated project, or reads its version.
"""

from __future__ import annotations

import importlib.metadata
import json
import re
import sys
import sysconfig
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

import meshcheck
from meshcheck.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_pyproject_builds_the_distribution_the_code_names():
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    assert project["name"] == meshcheck.DISTRIBUTION == "meshcheck-assembly"
    assert project["scripts"] == {"meshcheck": "meshcheck.cli:main"}


def test_version_is_read_under_the_distribution_name():
    version = importlib.metadata.version(meshcheck.DISTRIBUTION)
    result = CliRunner().invoke(main, ["--version"], prog_name="meshcheck")
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"meshcheck, version {version}"


def test_help_and_sarif_point_at_the_distribution():
    result = CliRunner().invoke(main, ["--help"], terminal_width=200)
    assert f'pip install "{meshcheck.DISTRIBUTION}[dask]"' in " ".join(result.output.split())
    samples = [str(ROOT / "sample_meshes" / n) for n in ("plate.stl", "bracket.stl")]
    result = CliRunner().invoke(main, [*samples, "--no-cache", "--no-config", "--format", "sarif"])
    driver = json.loads(result.stdout)["runs"][0]["tool"]["driver"]
    assert driver["informationUri"] == f"https://pypi.org/project/{meshcheck.DISTRIBUTION}/"


def test_readme_installs_the_distribution():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```(?:sh|yaml)\n(.*?)```", readme, flags=re.DOTALL)
    installs = [
        m[1].strip("\"'")
        for block in blocks
        for m in re.finditer(r"pip install (?:-\w+ )*(\S+)", block)
        if not m[1].startswith((".", '".')) and "meshcheck" in m[1]  # not a bench's extra tools
    ]
    assert installs and all(i.startswith(meshcheck.DISTRIBUTION) for i in installs), installs
    assert '"meshcheck[dask]"' not in readme


@pytest.mark.skipif(
    sys.platform == "win32" or sysconfig.get_config_var("Py_GIL_DISABLED"),
    reason="Windows names a stable-ABI module _kernels.pyd; free-threaded: no stable ABI",
)
def test_kernels_are_built_on_the_stable_abi():
    from meshcheck.geometry import _kernels

    assert ".abi3." in Path(_kernels.__file__).name, _kernels.__file__


@pytest.mark.slow
def test_wheel_tests_skip_only_tests_that_exist():
    """Every test the wheels' test commands deselect or ignore (pyproject.toml,
    [tool.cibuildwheel]) is still there under that name: a rename would silently run it where
    it cannot pass, or deselect nothing while seeming to."""
    import shlex
    import subprocess

    with open(ROOT / "pyproject.toml", "rb") as f:
        cibw = tomllib.load(f)["tool"]["cibuildwheel"]
    commands = [cibw["test-command"]] + [cibw[p]["test-command"] for p in ("macos", "windows")]
    collected = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", "tests"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    ).stdout.splitlines()
    for command in commands:
        args = shlex.split(command)
        terms = re.findall(r"not (\w+)", args[args.index("-k") + 1])
        assert "in_chromium" in terms
        for term in terms:
            assert any(term in node for node in collected), term
        ignored = [args[i + 1] for i, a in enumerate(args) if a == "--ignore"]
        assert all((ROOT / path).is_file() for path in ignored), ignored
    chromium = [node for node in collected if "in_chromium" in node]
    assert len(chromium) == 2 and all("test_html_report.py" in n for n in chromium), chromium
