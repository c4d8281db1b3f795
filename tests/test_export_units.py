"""The ``--export`` glTF is in metres, as glTF defines its lengths, whatever the report's unit:
it opens at its true size in a viewer and reads back into meshcheck without a size warning."""

from __future__ import annotations

import glob
import json
import os
import struct

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from meshcheck.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLE = sorted(glob.glob(os.path.join(ROOT, "sample_meshes", "*.stl")))


def glb_json(path) -> dict:
    raw = open(path, "rb").read()
    (length,) = struct.unpack_from("<I", raw, 12)
    return json.loads(raw[20 : 20 + length])


def run(args):
    return CliRunner().invoke(main, [*args, "--no-config", "-j", "1"])


@pytest.mark.parametrize(("units", "metres"), [("mm", 1e-3), ("in", 0.0254), ("m", 1.0)])
def test_the_export_is_in_metres_and_keeps_the_report_unit(tmp_path, units, metres):
    path = tmp_path / "clashes.glb"
    result = run([*SAMPLE, "--units", units, "--export", str(path), "--cache-dir", str(tmp_path)])
    assert result.exit_code == 1, result.stderr
    assert glb_json(path)["scenes"][0]["extras"] == {"meshcheck": {"report_units": units}}
    scene = trimesh.load_scene(str(path))
    plate = trimesh.load_mesh(os.path.join(ROOT, "sample_meshes", "plate.stl"))
    exported = scene.geometry[scene.graph[SAMPLE[-1]][1]]  # plate.stl, named by its path
    np.testing.assert_allclose(exported.bounds, plate.bounds * metres, rtol=1e-6)
    clash = next(n for n in scene.graph.nodes_geometry if n.startswith("interference"))
    volume = scene.geometry[scene.graph[clash][1]].volume  # 159.5 cubic report units
    assert volume == pytest.approx(159.5 * metres**3, rel=1e-3)


def test_meshcheck_reads_its_own_export_without_a_size_warning(tmp_path):
    path = tmp_path / "clashes.glb"
    first = run([*SAMPLE, "--export", str(path), "--cache-dir", str(tmp_path)])
    assert first.exit_code == 1
    again = run([str(path), "--cache-dir", str(tmp_path)])
    assert "across" not in again.stderr and "mixed units" not in again.stderr, again.stderr
    assert again.stdout.splitlines()[-1].startswith("FAIL: 7 parts")  # six parts and the clash
    # the bolt's interference with the plate, as the first run measured it, now in metres
    assert "depth 0.0006983" in again.stdout
