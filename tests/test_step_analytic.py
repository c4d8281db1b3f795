"""STEP solids whose planes and cylinders are written as B-splines: decided on the solids rebuilt
on analytic geometry (``meshcheck.verify.analytic``), with the verdicts and figures of the
solids as written.

The oracles: the same parts built from OpenCASCADE's primitives (planes and cylinders, never
converted), closed forms of their fits, and the pairs of every test STEP file decided on the
solids as read, without the rebuild, their shared volume integrated adaptively (OpenCASCADE's
default quadrature of a B-spline solid can be far off, which is why the rebuild's volume is
compared with the adaptive one).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from step_writer import annulus_volume, box, cut, cylinder, placement, write_step

from meshcheck.cli import main
from meshcheck.load import load_bodies
from meshcheck.pipeline import check_bodies
from meshcheck.verify import analytic, solids

BOX_SIDES = str(Path(__file__).parent / "data" / "step" / "box_sides.STEP")
EYE = np.eye(4)


def nurbs(shape):
    """``shape`` with every face and edge written as a B-spline (as some CAD systems export)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert

    return BRepBuilderAPI_NurbsConvert(shape, True).Shape()


def surface_kinds(shape) -> list[str]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    kinds, explorer = [], TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        kinds.append(BRepAdaptor_Surface(TopoDS.Face(explorer.Current())).GetType().name)
        explorer.Next()
    return sorted(kinds)


def exact_volume(shape) -> float:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props, 1e-12)
    return props.Mass()


def plate_with_hole(hole: float):
    return cut(box((-10, -10, 0), (10, 10, 5)), cylinder(hole, -1, 6))


def fits_file(tmp_path) -> str:
    """Pins in the holes of plates, every face a B-spline: line to line, 0.2 mm clear, 0.01 mm
    into the plate, and a pin off its hole's axis."""
    plate, pins = nurbs(plate_with_hole(3.0)), {}
    for name, radius in (("line", 3.0), ("loose", 2.8), ("tight", 3.01)):
        pins[name] = nurbs(cylinder(radius, -3, 8))
    products = {"plate": plate, **pins}
    instances = []
    for k, name in enumerate(("line", "loose", "tight", "line")):
        shift = (30.0 * k, 0.0, 0.0)
        instances.append(("plate", placement(shift)))
        offset = (30.0 * k + (0.05 if k == 3 else 0.0), 0.0, 0.0)
        instances.append((name, placement(offset)))
    return str(write_step(tmp_path / "fits.step", products, instances))


# --------------------------------------------------------------------------------------------
# Known answers


def test_b_spline_planes_and_cylinders_are_rebuilt_as_planes_and_cylinders():
    plate = nurbs(plate_with_hole(3.0))
    assert set(surface_kinds(plate)) == {"GeomAbs_BSplineSurface"}
    rebuilt = analytic.analytic(plate)
    assert surface_kinds(rebuilt) == ["GeomAbs_Cylinder"] + ["GeomAbs_Plane"] * 6
    assert exact_volume(rebuilt) == pytest.approx(20 * 20 * 5 - math.pi * 9 * 5, rel=1e-12)


def test_a_free_form_solid_and_an_analytic_one_are_kept_as_they_are():
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeWire
    from OCP.BRepOffsetAPI import BRepOffsetAPI_ThruSections
    from OCP.gp import gp_Ax2, gp_Circ, gp_Dir, gp_Pnt

    loft = BRepOffsetAPI_ThruSections(True, False)  # a bulging solid through three circles
    for z, radius in ((0.0, 2.0), (1.0, 3.0), (2.0, 2.0)):
        circle = gp_Circ(gp_Ax2(gp_Pnt(0, 0, z), gp_Dir(0, 0, 1)), radius)
        loft.AddWire(BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(circle).Edge()).Wire())
    loft.Build()
    free_form = loft.Shape()
    assert "GeomAbs_BSplineSurface" in surface_kinds(free_form)
    assert analytic.analytic(free_form) is free_form
    primitive = plate_with_hole(3.0)
    assert analytic.analytic(primitive) is primitive


def test_fits_of_b_spline_parts_read_their_closed_forms(tmp_path):
    findings = check_bodies(load_bodies([fits_file(tmp_path)]), clearance=0.25, jobs=1).findings
    statuses = sorted((f.status, round(f.distance, 9)) for f in findings)
    assert statuses == [
        ("clearance", 0.2),
        ("interference", 0.0),
        ("interference", 0.0),
        ("touching", 0.0),
    ]
    tight = [f for f in findings if f.status == "interference" and f.depth < 0.02]
    (tight,) = tight
    assert tight.volume == pytest.approx(annulus_volume(3.0, 3.01, 5.0), rel=1e-9)
    assert tight.depth == pytest.approx(0.01, rel=1e-6)


# --------------------------------------------------------------------------------------------
# Every test STEP file: the rebuilt solids decide as the solids as read


def _recorded_pairs(path: str, monkeypatch) -> list[tuple]:
    """Every pair a run decides on the B-rep, on the solids as read (no rebuild): the two
    products, their relative placement, the options, and the verdict."""
    calls = []
    decide_pair = solids.decide_pair

    def recording(a, b, relative, **options):
        verdict = decide_pair(a, b, relative, **options)
        calls.append((a, b, relative, options, verdict))
        return verdict

    with monkeypatch.context() as patch:
        patch.setattr(analytic, "analytic", lambda shape: shape)
        patch.setattr(solids, "decide_pair", recording)
        result = CliRunner().invoke(main, [path, "-j", "1", "--no-cache", "--clearance", "0.5"])
    assert result.exit_code in (0, 1), result.output
    return calls


@pytest.mark.parametrize("name", ["box_sides", "fits"])
def test_every_pair_of_the_test_files_decides_the_same_on_the_rebuilt_solids(
    name, tmp_path, monkeypatch
):
    path = BOX_SIDES if name == "box_sides" else fits_file(tmp_path)
    calls = _recorded_pairs(path, monkeypatch)
    assert len(calls) >= 4
    for a, b, relative, options, verdict in calls:
        rebuilt = solids.decide_pair(
            analytic.analytic(a), analytic.analytic(b), relative, **options
        )
        assert rebuilt.status == verdict.status
        assert rebuilt.distance == pytest.approx(verdict.distance, rel=1e-6, abs=1e-12)
        if verdict.volume is not None:
            moved = b.Moved(solids._location(relative))
            shared = solids._Intersection(a, moved).shared
            assert rebuilt.volume == pytest.approx(exact_volume(shared), rel=1e-6)


@pytest.mark.parametrize("name", ["box_sides", "fits"])
def test_reports_of_the_test_files_are_the_same_with_and_without_the_rebuild(
    name, tmp_path, monkeypatch
):
    path = BOX_SIDES if name == "box_sides" else fits_file(tmp_path)
    arguments = [path, "-j", "1", "--no-cache", "--format", "json", "--clearance", "0.5"]

    def report(rebuild: bool) -> dict:
        with monkeypatch.context() as patch:
            if not rebuild:
                patch.setattr(analytic, "analytic", lambda shape: shape)
            output = CliRunner().invoke(main, arguments).stdout
        results = json.loads(output)["results"]
        for result in results:  # where a touching pair meets is a box around the section
            result.pop("location")
        return results

    before, after = report(False), report(True)
    if name == "box_sides":
        assert after == before
    else:  # the same volumes, integrated adaptively on the B-splines; depths certified apart
        for old, new in zip(before, after, strict=True):
            assert old["status"] == new["status"]
            assert new["distance"] == pytest.approx(old["distance"], rel=1e-6, abs=1e-12)
            if old["status"] == "interference":
                assert new["volume"] == pytest.approx(old["volume"], rel=1e-6)


def test_an_interference_of_b_spline_solids_as_read_has_its_closed_form_volume(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(analytic, "analytic", lambda shape: shape)
    findings = check_bodies(load_bodies([fits_file(tmp_path)]), jobs=1, cache_dir=None).findings
    (tight,) = [f for f in findings if f.status == "interference" and f.depth < 0.02]
    assert tight.volume == pytest.approx(annulus_volume(3.0, 3.01, 5.0), rel=1e-6)


# --------------------------------------------------------------------------------------------
# Property: a pin in a hole, written as B-splines, decides as the primitives


@settings(max_examples=12, deadline=None, derandomize=True)
@given(
    hole=st.sampled_from([3.0, 3.005]),
    pin=st.sampled_from([2.99, 3.0, 3.004, 3.01]),
    offset=st.sampled_from([0.0, 0.002, 0.05]),
    angle=st.floats(0.0, 90.0),
)
def test_a_b_spline_pin_in_a_b_spline_hole_decides_as_the_primitives(hole, pin, offset, angle):
    plate, rod = plate_with_hole(hole), cylinder(pin, -3, 8, x=offset)
    rotation = solids._location(placement(angle_deg=angle))
    plate, rod = plate.Moved(rotation), rod.Moved(rotation)
    truth = solids.decide(plate, rod, tolerance=1e-3, clearance=0.02)
    rebuilt = solids.decide(
        analytic.analytic(nurbs(plate)),
        analytic.analytic(nurbs(rod)),
        tolerance=1e-3,
        clearance=0.02,
    )
    assert rebuilt.status == truth.status
    assert rebuilt.distance == pytest.approx(truth.distance, rel=1e-6, abs=1e-12)
    assert rebuilt.volume == pytest.approx(truth.volume, rel=1e-6, abs=1e-12)
