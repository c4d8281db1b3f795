"""One version, from ``pyproject.toml``: the same in ``meshcheck --version``, the installed
metadata (what the wheel carries), ``meshcheck.__version__``, the reports that name a tool
version (SARIF, HTML) and the documentation. And ``--help`` names every input and unit."""

from __future__ import annotations

import glob
import json
import os
import re
import tomllib
from importlib import metadata

import pytest
from click.testing import CliRunner

import meshcheck
from meshcheck.cli import main
from meshcheck.pipeline import check
from meshcheck.reports import render
from meshcheck.units import METRES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def pyproject_version() -> str:
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as fh:
        return tomllib.load(fh)["project"]["version"]


def test_one_version_everywhere_it_is_read():
    version = pyproject_version()
    assert re.fullmatch(r"\d+\.\d+\.\d+", version)
    assert metadata.version(meshcheck.DISTRIBUTION) == version  # the installed (wheel) metadata
    assert meshcheck.__version__ == version
    out = CliRunner().invoke(main, ["--version"]).stdout
    assert out == f"main, version {version}\n" or out == f"meshcheck, version {version}\n"


def test_the_reports_name_the_same_version(monkeypatch):
    monkeypatch.chdir(ROOT)
    result = check(["sample_meshes/plate.stl", "sample_meshes/bracket.stl"], config=None, jobs=1)
    sarif = json.loads(render(result, "sarif"))
    assert sarif["runs"][0]["tool"]["driver"]["version"] == pyproject_version()
    page = render(result, "html")
    data = json.loads(re.search(r'id="meshcheck-data">(.*?)</script>', page).group(1))
    assert data["version"] == pyproject_version()


#: How the documentation names a release: the action's and the hook's tag, a pinned install.
RELEASE_MENTIONS = re.compile(
    r"meshcheck@v(\d[\w.]*)|rev: v(\d[\w.]*)|meshcheck-assembly==(\d[\w.]*)"
)


def documents() -> list[str]:
    found = [os.path.join(ROOT, "README.md"), os.path.join(ROOT, ".pre-commit-hooks.yaml")]
    found += sorted(glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True))
    return [path for path in found if os.path.exists(path)]


def test_the_documentation_names_this_version():
    if not os.path.isdir(os.path.join(ROOT, "docs")):
        pytest.skip("docs/ is not beside the tests (a wheel's test copy)")
    version = pyproject_version()
    mentions = []
    for path in documents():
        with open(path, encoding="utf-8") as fh:
            for match in RELEASE_MENTIONS.finditer(fh.read()):
                mentions.append((os.path.relpath(path, ROOT), next(g for g in match.groups() if g)))
    assert len(mentions) >= 4, mentions
    assert [m for m in mentions if m[1] != version] == []
    with open(os.path.join(ROOT, "CHANGELOG.md"), encoding="utf-8") as fh:
        assert f"## [{version}]" in fh.read()


def test_help_names_every_input_and_every_unit():
    text = CliRunner().invoke(main, ["--help"], terminal_width=200).stdout
    flat = " ".join(text.split())
    for kind in ("STL", "OBJ", "PLY", "OFF", "GLB/GLTF", "3MF", "STEP", "URDF"):
        assert kind in flat
    units = re.search(r"Units: ([^(]*) \(", flat).group(1)
    assert units.split(", ") == list(METRES)  # the one unit table, in its order
