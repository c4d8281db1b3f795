"""End-to-end cases: every folder in tests/cases runs through the whole pipeline.

Each folder holds the meshes of one small assembly and ``expected.json`` (written, with the truth
computed independently of the verify stage, by ``tests/make_cases.py``): every finding listed must
be reported with that status, every pair not listed must be clear.
"""

from __future__ import annotations

import glob
import json
import os

import pytest

from meshcheck.pipeline import check

CASES = sorted(glob.glob(os.path.join(os.path.dirname(__file__), "cases", "*", "expected.json")))


def test_cases_exist():
    assert len(CASES) >= 9


@pytest.mark.parametrize(
    "expected_path", CASES, ids=[os.path.basename(os.path.dirname(p)) for p in CASES]
)
def test_case(expected_path, tmp_path):
    folder = os.path.dirname(expected_path)
    with open(expected_path) as fh:
        expected = json.load(fh)
    files = sorted(glob.glob(os.path.join(folder, "*.stl")))
    result = check(files, clearance=expected["options"]["clearance"], cache_dir=str(tmp_path))

    got = {(os.path.basename(f.a), os.path.basename(f.b)): f for f in result.findings}
    want = {(e["a"], e["b"]): e for e in expected["findings"]}
    assert {k: f.status for k, f in got.items()} == {k: e["status"] for k, e in want.items()}
    for key, e in want.items():
        f = got[key]
        if "distance" in e:
            assert f.distance == pytest.approx(e["distance"], abs=1e-3), key
        if "volume" in e:
            assert f.volume == pytest.approx(e["volume"], rel=1e-6), key
        if "depth" in e:
            assert f.depth == pytest.approx(e["depth"], rel=0.03), key
        assert f.location is not None, key
        assert not f.is_surface_only, key
