"""Every report format and the glTF export pinned by a snapshot, for the sample assembly and
every end-to-end case (ruff's emitters are the model: one snapshot per format).

Each fixture (``sample``: ``sample_meshes/*.stl``; ``sample-tests``: the same with the clash
tests of ``SAMPLE_TESTS``; ``robot-arm``: ``sample_meshes/arm.urdf`` at a pose, its ``arm.srdf``
audited; ``case-NAME``: the STL files of ``tests/cases/NAME`` with the options of its
``expected.json``) is checked from the repository
root with relative paths, one process, no configuration file, and a fresh pair cache; it is then
checked again against that warm cache, and both runs' outputs must equal the files under
``tests/data/snapshots/FIXTURE/`` byte for byte (a report is a function of the inputs and options,
never of cache state).

Volatile bits are normalised deliberately, each checked first to be what it should be:

- SARIF: the tool version (must be meshcheck's installed version) and the source root (must be
  the working directory's ``file://`` URI) become ``VERSION`` and ``file:///SRCROOT/``;
- HTML: the snapshot holds the embedded data JSON (its ``version`` checked, then ``VERSION``),
  the SHA-256 of the geometry it embeds *after* gunzip (gzip's bytes depend on the zlib build),
  and the SHA-256 of the page with both embedded scripts' contents cut out (template, styles,
  three.js, the viewer);
- glTF (``.gltf``): the JSON with each embedded buffer replaced by its length and SHA-256;
  ``.glb``: its JSON chunk, and its binary chunk's length and SHA-256.

To regenerate after an intended change, run::

    MESHCHECK_UPDATE_SNAPSHOTS=1 .venv/bin/python -m pytest -q tests/test_report_snapshots.py

and review ``git diff tests/data/snapshots`` before committing.
"""

from __future__ import annotations

import base64
import glob
import gzip
import hashlib
import json
import os
import re
import struct
import urllib.parse
from importlib import metadata

import pytest

import meshcheck
from meshcheck.pipeline import check
from meshcheck.reports import FORMATS, render
from meshcheck.reports.gltf import export_clashes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SNAPSHOTS = os.path.join(ROOT, "tests", "data", "snapshots")
UPDATE = os.environ.get("MESHCHECK_UPDATE_SNAPSHOTS") == "1"

#: Snapshot file of each report format.
REPORT_FILES = {
    "text": "report.txt",
    "json": "report.json",
    "junit": "report.junit.xml",
    "github": "report.github.txt",
    "sarif": "report.sarif.json",
    "markdown": "report.md",
    "html": "report.html.json",
}


#: Clash tests on the sample: those of the configuration guide, and one at its own tolerance.
SAMPLE_TESTS = [
    "wrench access:bracket.stl:bolt_*:clearance=15",
    "fasteners:bolt_*:plate.stl",
    "everything:*:*",
    "seated:bolt_*:plate.stl:tolerance=0.001:fail_on=touching",
]


def _fixtures() -> dict[str, tuple[list[str], dict]]:
    """Fixture name -> (relative paths, options of ``check``)."""
    sample = sorted(glob.glob("sample_meshes/*.stl", root_dir=ROOT))
    out = {"sample": (sample, {}), "sample-tests": (sample, {"tests": SAMPLE_TESTS})}
    # a robot at a pose, its SRDF audited: the pose and the audit in every format
    audit = {"pose": "shoulder=1.5,elbow=160deg", "audit": "sample_meshes/arm.srdf"}
    out["robot-arm"] = (["sample_meshes/arm.urdf"], {"motion": audit})
    for expected in sorted(glob.glob("tests/cases/*/expected.json", root_dir=ROOT)):
        folder = os.path.dirname(expected)
        with open(os.path.join(ROOT, expected)) as fh:
            options = json.load(fh)["options"]
        files = sorted(glob.glob(f"{folder}/*.stl", root_dir=ROOT))
        out[f"case-{os.path.basename(folder)}"] = (files, options)
    return out


FIXTURES = _fixtures()


def test_every_format_has_a_snapshot_file():
    assert set(REPORT_FILES) == set(FORMATS)
    assert len(FIXTURES) >= 10


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_reports_match_their_snapshots(name, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "snapshot tests")
    paths, options = FIXTURES[name]
    cache = str(tmp_path / "cache")
    runs = []
    for run in ("cold", "warm"):
        result = check(paths, config=None, cache_dir=cache, jobs=1, **options)
        runs.append(_outputs(result, paths, tmp_path / run))
    cold, warm = runs
    folder = os.path.join(SNAPSHOTS, name)
    if UPDATE:
        os.makedirs(folder, exist_ok=True)
        for file, text in cold.items():
            with open(os.path.join(folder, file), "w", encoding="utf-8", newline="") as fh:
                fh.write(text)
    stored = {}
    for file in cold:
        with open(os.path.join(folder, file), encoding="utf-8", newline="") as fh:
            stored[file] = fh.read()
    for file in cold:
        assert cold[file] == stored[file], f"{name}/{file} differs from its snapshot"
        assert warm[file] == stored[file], f"{name}/{file} differs with a warm pair cache"


def _outputs(result, paths: list[str], where) -> dict[str, str]:
    """Snapshot file name -> normalised text, for every format and both export types."""
    out = {}
    for fmt, file in REPORT_FILES.items():
        text = render(result, fmt, inputs=paths)
        out[file] = _NORMALISE.get(fmt, lambda t: t)(text)
    where.mkdir()
    for ext in ("glb", "gltf"):
        path = str(where / f"clashes.{ext}")
        export_clashes(path, result.bodies, result.findings, units=result.units)
        with open(path, "rb") as fh:
            data = fh.read()
        out[f"export.{ext}.json"] = _glb(data) if ext == "glb" else _gltf(data)
    return out


def _version() -> str:
    return metadata.version(meshcheck.DISTRIBUTION)


def _sarif(text: str) -> str:
    doc = json.loads(text)
    # Re-serialising gives the report's own bytes, so only the two fields below are changed.
    assert json.dumps(doc, indent=2, ensure_ascii=True, allow_nan=False) + "\n" == text
    run = doc["runs"][0]
    assert run["tool"]["driver"]["version"] == _version()
    srcroot = "file://" + urllib.parse.quote(os.fsencode(os.getcwd())).rstrip("/") + "/"
    assert run["originalUriBaseIds"]["%SRCROOT%"]["uri"] == srcroot
    run["tool"]["driver"]["version"] = "VERSION"
    run["originalUriBaseIds"]["%SRCROOT%"]["uri"] = "file:///SRCROOT/"
    normal = json.dumps(doc, indent=2, ensure_ascii=True, allow_nan=False) + "\n"
    return normal


_SCRIPT = re.compile(
    r'(<script type="application/[a-z-]+" id="meshcheck-([a-z]+)">)(.*?)(</script>)'
)


def _html(page: str) -> str:
    scripts = {m.group(2): m.group(3) for m in _SCRIPT.finditer(page)}
    assert set(scripts) == {"data", "geometry"}
    data = json.loads(scripts["data"])
    assert data["version"] == _version()
    data["version"] = "VERSION"
    geometry = gzip.decompress(base64.b64decode(scripts["geometry"]))
    shell = _SCRIPT.sub(lambda m: m.group(1) + m.group(4), page)
    doc = {
        "data": data,
        "geometry": {"bytes": len(geometry), "sha256": _sha(geometry)},
        "page_without_data_sha256": _sha(shell.encode()),
    }
    return json.dumps(doc, indent=1, ensure_ascii=True) + "\n"


def _gltf(raw: bytes) -> str:
    doc = json.loads(raw)
    for buffer in doc.get("buffers", []):
        head, _, payload = buffer.pop("uri").partition(",")
        assert head == "data:application/octet-stream;base64"
        data = base64.b64decode(payload)
        buffer["data"] = {"bytes": len(data), "sha256": _sha(data)}
    return json.dumps(doc, indent=1, ensure_ascii=True, sort_keys=True) + "\n"


def _glb(raw: bytes) -> str:
    magic, version, length = struct.unpack_from("<4sII", raw, 0)
    assert (magic, version, length) == (b"glTF", 2, len(raw))
    chunks, offset = {}, 12
    while offset < len(raw):
        size, kind = struct.unpack_from("<I4s", raw, offset)
        chunks[kind] = raw[offset + 8 : offset + 8 + size]
        offset += 8 + size
    doc = json.loads(chunks[b"JSON"])
    binary = chunks.get(b"BIN\0", b"")
    doc["binary_chunk"] = {"bytes": len(binary), "sha256": _sha(binary)}
    return json.dumps(doc, indent=1, ensure_ascii=True, sort_keys=True) + "\n"


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


_NORMALISE = {"sarif": _sarif, "html": _html}
