"""Depth = diameter of the largest ball inside the shared solid, against closed-form answers for
thin and curved overlaps (where sampling fails), an LP oracle for convex ones, numpy and
python-fcl point queries (never meshcheck's own) for a shell with no closed form, and the
touching / interference split at the tolerance, which must never rest on a depth that could be
too low."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from depth_shapes import annulus, crescent, lens, pin, prism_tube, tilted_slab_pair, wedge
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import brute_point_distances, brute_winding_numbers, fcl_point_distances
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from meshcheck import results
from meshcheck.mesh import outward_faces
from meshcheck.verify.depth import REL_GAP, depth_bounds
from meshcheck.verify.pair import shared_solid, verify_pair

SCALES = [1e-3, 1.0, 1e3]


def solid_of(a, b):
    va, vb = np.asarray(a.vertices, float), np.asarray(b.vertices, float)
    origin = 0.5 * (va.min(axis=0) + va.max(axis=0))
    va, vb = va - origin, vb - origin
    fa, fb = outward_faces(va, np.asarray(a.faces)), outward_faces(vb, np.asarray(b.faces))
    return shared_solid(va, fa, vb, fb)


def chebyshev_depth(*meshes):
    """Oracle for convex shared solids: the largest ball in the intersection of the meshes'
    face half-spaces (an LP), diameter."""
    n = np.concatenate([m.face_normals for m in meshes])
    h = np.einsum("ij,ij->i", n, np.concatenate([m.triangles[:, 0] for m in meshes]))
    lp = linprog([0, 0, 0, -1], A_ub=np.c_[n, np.ones(len(n))], b_ub=h, bounds=[(None, None)] * 4)
    return -2.0 * lp.fun


def assert_close_from_below(depth, want):
    """The reported depth is a ball shown to fit: never above the answer, and within 1e-3."""
    assert depth <= want * (1.0 + 1e-9)
    assert depth >= want * (1.0 - 1e-3)


# --- closed forms: thin curved shells --------------------------------------------------------


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("e, n", [(0.05, 24), (0.01, 96)])
def test_pin_too_big_for_its_hole_shares_a_shell_of_the_radial_excess(scale, e, n):
    a, b, want = annulus(scale, e, n)
    v = verify_pair(a, b, tolerance=1e-5 * scale, clearance=None)
    assert v.status == results.Verdict.INTERFERENCE
    assert_close_from_below(v.depth, want)


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("offset, n", [(0.1, 24), (0.02, 128)])
def test_pin_moved_sideways_in_its_hole_shares_a_crescent_of_the_offset(scale, offset, n):
    a, b, want = crescent(scale, offset, n)
    v = verify_pair(a, b, tolerance=1e-5 * scale, clearance=None)
    assert v.status == results.Verdict.INTERFERENCE
    assert_close_from_below(v.depth, want)


def test_the_faceted_answer_is_the_corner_ball_not_the_flat_middle():
    # Between facets the wall is e cos(pi/n) thick; the ball in the corner is larger. The depth
    # before this change stopped at the flat middle: 4.3e-3 low for 24 facets.
    a, b, want = crescent(1.0, 0.1, 24)
    assert want > 0.1 * np.cos(np.pi / 24) * (1 + 4e-3)
    v = verify_pair(a, b, tolerance=1e-5, clearance=None)
    assert_close_from_below(v.depth, want)


# --- convex overlaps: closed form and LP ------------------------------------------------------


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("press", [0.05, 0.004])
def test_wedge_pressed_into_a_block_shares_a_prism_of_known_inscribed_circle(scale, press):
    a, b, want = wedge(scale, press)
    v = verify_pair(a, b, tolerance=1e-6 * scale, clearance=None)
    assert v.status == results.Verdict.INTERFERENCE
    assert_close_from_below(v.depth, want)
    bounds = depth_bounds(*solid_of(a, b))
    assert bounds.is_certified and bounds.upper >= want * (1 - 1e-9)


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("overlap, count", [(0.02, 32), (0.002, 96)])
def test_two_spheres_overlapping_by_a_sliver_share_a_lens(scale, overlap, count):
    a, b, _ = lens(scale, overlap, count)
    want = chebyshev_depth(a, b)
    assert want == pytest.approx(overlap * scale, rel=0.02)  # the facets' tilt, no more
    v = verify_pair(a, b, tolerance=1e-6 * scale, clearance=None)
    assert v.status == results.Verdict.INTERFERENCE
    assert v.depth == pytest.approx(want, rel=1e-6)


# --- the bounds are proofs -----------------------------------------------------------------------


def test_the_ball_is_inside_and_the_upper_bound_is_above_every_sampled_ball():
    # A pin with 20 facets in a hole with 48, turned: a shell of varying thickness, no closed
    # form. The lower bound's ball must be inside (winding number) at its exact distance, and no
    # sampled point of the solid may hold a larger ball than the upper bound allows; inside and
    # distances from numpy over every triangle and from python-fcl, not meshcheck's kernels.
    plate = prism_tube(1.0, 3.0, 0.0, 1.0, 48)
    shaft = pin(1.03, -0.5, 1.5, 20)
    v, f = solid_of(plate, shaft)
    solid = trimesh.Trimesh(v, f, process=False)
    bounds = depth_bounds(v, f, max_boxes=150)
    centre = bounds.centre[None]
    assert brute_winding_numbers(solid, centre)[0] == pytest.approx(1.0, abs=1e-9)
    assert brute_point_distances(solid, centre)[0] == pytest.approx(0.5 * bounds.lower)
    assert fcl_point_distances(solid, centre)[0] == pytest.approx(0.5 * bounds.lower)
    rng = np.random.default_rng(0)
    points = rng.uniform(v.min(axis=0), v.max(axis=0), size=(20000, 3))
    inside = points[brute_winding_numbers(solid, points) > 0.5]
    assert len(inside) > 100
    sampled = 2.0 * brute_point_distances(solid, inside).max()
    assert sampled <= bounds.lower * (1 + 1e-9) <= bounds.upper
    assert sampled <= bounds.upper


@pytest.mark.parametrize("extents", [(1.0, 2.0, 3.0), (5.0, 4.0, 0.25), (1e-3, 1e-3, 1e-3)])
def test_a_box_holds_a_ball_as_wide_as_its_thinnest_side(extents):
    box = trimesh.creation.box(extents=extents)
    v = box.vertices @ Rotation.random(random_state=1).as_matrix().T + 100.0 * max(extents)
    bounds = depth_bounds(v, box.faces)
    assert bounds.is_certified
    assert_close_from_below(bounds.lower, min(extents))
    assert bounds.upper >= min(extents) * (1 - 1e-9)


@settings(derandomize=True, deadline=None, max_examples=30)
@given(st.integers(0, 2**32 - 1), st.integers(5, 40), st.sampled_from(SCALES))
def test_bounds_bracket_the_linear_programs_ball_in_a_convex_solid(seed, count, scale):
    # A convex solid (the hull of random points, flattened along a random axis): the largest
    # ball is the Chebyshev ball of its face half-spaces, scipy's LP.
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(count, 3)) * [1.0, 1.0, rng.uniform(0.05, 1.0)]
    rotation = Rotation.random(random_state=seed).as_matrix()
    solid = trimesh.Trimesh(scale * points @ rotation.T).convex_hull
    want = chebyshev_depth(solid)
    bounds = depth_bounds(solid.vertices, solid.faces)
    assert bounds.lower <= want * (1 + 1e-9)
    assert bounds.upper >= want * (1 - 1e-9)
    assert bounds.lower >= want * (1 - REL_GAP)  # found, not merely bracketed


@pytest.mark.parametrize("scale", SCALES)
def test_depth_is_the_same_after_a_rigid_motion(scale):
    a, b, want = crescent(scale, 0.05, 32)
    turn = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    motion = np.eye(4)
    motion[:3, :3] = turn
    motion[:3, 3] = [7.0 * scale, -3.0 * scale, 100.0 * scale]
    moved = verify_pair(
        a.copy().apply_transform(motion),
        b.copy().apply_transform(motion),
        tolerance=1e-5 * scale,
        clearance=None,
    )
    assert_close_from_below(moved.depth, want)


# --- touching only on proof -----------------------------------------------------------------------


@pytest.mark.parametrize("scale", SCALES)
def test_a_flat_sliver_thinner_than_the_tolerance_touches_and_a_thicker_one_interferes(scale):
    tol = 1e-3 * scale
    thin = verify_pair(*tilted_slab_pair(scale, 0.3e-3)[:2], tolerance=tol, clearance=None)
    assert thin.status == results.Verdict.TOUCHING
    a, b, want = tilted_slab_pair(scale, 3e-3)
    thick = verify_pair(a, b, tolerance=tol, clearance=None)
    assert thick.status == results.Verdict.INTERFERENCE
    assert thick.depth == pytest.approx(want, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_a_curved_sliver_thinner_than_the_tolerance_touches_and_a_thicker_one_interferes(scale):
    tol = 1e-3 * scale
    a, b, _ = annulus(scale, 0.3e-3, 128)
    assert verify_pair(a, b, tolerance=tol, clearance=None).status == results.Verdict.TOUCHING
    a, b, want = annulus(scale, 3e-3, 128)
    thick = verify_pair(a, b, tolerance=tol, clearance=None)
    assert thick.status == results.Verdict.INTERFERENCE
    assert_close_from_below(thick.depth, want)


def test_upper_bound_proves_a_thin_convex_overlap_touching_without_a_search():
    a, b, want = tilted_slab_pair(1.0, 1e-4)
    bounds = depth_bounds(*solid_of(a, b), decide_at=1e-3)
    assert bounds.upper <= 1e-3 and bounds.boxes == 0
    assert bounds.upper >= want * (1 - 1e-9)
