"""End-to-end cases: every folder in tests/cases runs through the whole pipeline.

Each folder holds the meshes of one small assembly and ``expected.json`` (written, with the truth
computed independently of the verify stage, by ``tests/make_cases.py``): every finding listed must
be reported with that status, every pair not listed must be clear. The volumes written are checked
again here against the meshes as stored, and the volume oracle against prisms of known volume.
"""

from __future__ import annotations

import glob
import json
import math
import os

import pytest
import trimesh
from depth_shapes import prism_tube
from make_cases import box, cylinder, shared_volume

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


def test_expected_volumes_are_the_cross_section_volumes_of_the_stored_meshes():
    volumes = 0
    for expected_path in CASES:
        folder = os.path.dirname(expected_path)
        with open(expected_path) as fh:
            findings = json.load(fh)["findings"]
        for f in findings:
            if "volume" in f:
                a, b = (trimesh.load_mesh(os.path.join(folder, f[k])) for k in ("a", "b"))
                assert shared_volume(a, b) == pytest.approx(f["volume"], rel=1e-12), folder
                volumes += 1
    assert volumes == 3


def regular_polygon_area(radius: float, sides: int) -> float:
    return 0.5 * sides * radius**2 * math.sin(2.0 * math.pi / sides)


def test_shared_volume_of_prisms_with_known_volumes():
    a = box([0, 0, 0], [2, 3, 4])
    assert shared_volume(a, box([1, 1, 1], [5, 5, 5])) == pytest.approx(1 * 2 * 3, rel=1e-14)
    assert shared_volume(a, box([0, 0, -1], [2, 3, 9])) == pytest.approx(24, rel=1e-14)
    assert shared_volume(a, box([2, 0, 0], [3, 3, 4])) == 0.0  # face to face
    # a 24-gon pin of radius 3.5 through a 24-gon hole of radius 3.3 in a plate 10 thick (a tube
    # whose coordinates are exact: no boolean rounds them): the ring between the polygons
    plate = prism_tube(3.3, 7.0, 0.0, 10.0, 24)
    ring = regular_polygon_area(3.5, 24) - regular_polygon_area(3.3, 24)
    assert shared_volume(plate, cylinder(3.5, -4, 20)) == pytest.approx(10 * ring, rel=1e-12)
    assert shared_volume(plate, cylinder(3.2, -4, 20)) == 0.0  # in the hole, clear of it
    buried = cylinder(1.0, 2, 5, x=5.0)  # in the tube's wall
    assert shared_volume(plate, buried) == pytest.approx(3 * regular_polygon_area(1, 24), rel=1e-12)
