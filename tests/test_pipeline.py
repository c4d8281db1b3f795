"""The pipeline's own decisions: which pairs reach which stage, and what comes out."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from meshcheck.config import Approval, Groups
from meshcheck.load import Body
from meshcheck.outcome import exit_status
from meshcheck.pipeline import check_bodies


def box_body(name: str, lower, upper) -> Body:
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    mesh = trimesh.creation.box(extents=upper - lower)
    mesh.apply_translation(0.5 * (lower + upper))
    return Body(name, name, mesh)


def ring_body(name: str, centre, r_min=1.0, r_max=2.0, height=1.0) -> Body:
    mesh = trimesh.creation.annulus(r_min=r_min, r_max=r_max, height=height, sections=24)
    return Body(name, name, mesh, trimesh.transformations.translation_matrix(centre))


def test_parts_whose_hulls_are_apart_are_never_decomposed(tmp_path):
    bodies = [ring_body("ring_a", [0, 0, 0]), ring_body("ring_b", [10, 0, 0])]
    result = check_bodies(bodies, cache_dir=str(tmp_path))
    assert result.findings == []
    assert [p.pieces for p in result.parts] == [0, 0]


def test_overlapping_boxes_interfere_with_exact_depth_and_volume():
    bodies = [box_body("a", [0, 0, 0], [1, 1, 1]), box_body("b", [0.7, 0, 0], [1.7, 1, 1])]
    result = check_bodies(bodies, cache_dir=None)
    (finding,) = result.findings
    assert (finding.a, finding.b, finding.status) == ("a", "b", "interference")
    assert finding.distance == 0.0
    assert finding.depth == pytest.approx(0.3, rel=0.05)
    assert finding.volume == pytest.approx(0.3, rel=1e-6)
    assert exit_status(result) == 1


def test_face_to_face_boxes_touch_and_pass():
    bodies = [box_body("a", [0, 0, 0], [1, 1, 1]), box_body("b", [1, 0, 0], [2, 1, 1])]
    result = check_bodies(bodies, cache_dir=None)
    assert [(f.status, f.distance) for f in result.findings] == [("touching", 0.0)]
    assert exit_status(result) == 0


def test_clearance_reports_the_true_gap():
    bodies = [box_body("a", [0, 0, 0], [1, 1, 1]), box_body("b", [1.25, 0, 0], [2, 1, 1])]
    assert check_bodies(bodies, cache_dir=None).findings == []
    (finding,) = check_bodies(bodies, cache_dir=None, clearance=0.5).findings
    assert finding.status == "clearance"
    assert finding.distance == pytest.approx(0.25, abs=1e-9)


def test_peg_in_ring_hole_is_clear_although_hulls_overlap(tmp_path):
    # The ring's hull fills its hole; only the pieces and the real meshes tell the peg is free.
    ring = ring_body("ring", [0, 0, 0], r_min=1.0, r_max=2.0)
    peg = box_body("peg", [-0.5, -0.5, -2], [0.5, 0.5, 2])
    result = check_bodies([ring, peg], cache_dir=str(tmp_path))
    assert result.findings == []


def test_part_buried_inside_another_interferes():
    outer = box_body("outer", [0, 0, 0], [10, 10, 10])
    inner = box_body("inner", [4, 4, 4], [5, 5, 5])
    (finding,) = check_bodies([outer, inner], cache_dir=None).findings
    assert finding.status == "interference"
    assert finding.volume == pytest.approx(1.0, rel=1e-6)


def test_groups_check_only_across_the_two_sets():
    bodies = [
        box_body("bolt1", [0, 0, 0], [1, 1, 1]),
        box_body("bolt2", [0.5, 0, 0], [1.5, 1, 1]),
        box_body("plate", [5, 5, 5], [6, 6, 6]),
    ]
    everything = check_bodies(bodies, cache_dir=None)
    assert [(f.a, f.b) for f in everything.findings] == [("bolt1", "bolt2")]
    across = check_bodies(bodies, cache_dir=None, groups=Groups(("bolt*",), ("plate",)))
    assert across.findings == []


def test_approved_interference_is_reported_but_does_not_fail():
    bodies = [box_body("shaft", [0, 0, 0], [1, 1, 1]), box_body("hub", [0.9, 0, 0], [2, 1, 1])]
    approvals = [Approval("hub", "sha*", "press fit")]
    result = check_bodies(bodies, cache_dir=None, approvals=approvals)
    (finding,) = result.findings
    assert finding.approval_reason == "press fit"
    assert exit_status(result) == 0


def test_finding_ids_are_stable_and_order_free():
    a, b = box_body("a", [0, 0, 0], [1, 1, 1]), box_body("b", [0.5, 0, 0], [1.5, 1, 1])
    first = check_bodies([a, b], cache_dir=None).findings[0].id
    second = check_bodies([b, a], cache_dir=None).findings[0].id
    assert first == second and len(first) == 12


def test_loading_reports_progress_per_file():
    from meshcheck.load import load_bodies

    seen = []
    load_bodies(
        ["sample_meshes/plate.stl", "sample_meshes/bracket.stl"],
        progress=lambda done, total: seen.append((done, total)),
    )
    assert seen == [(1, 2), (2, 2)]
