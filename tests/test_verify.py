"""The verify stage: known answers on small meshes, then properties against independent oracles."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from meshes import box_between, fcl_collide, fcl_distance
from scipy.optimize import linprog, minimize

from meshcheck import results
from meshcheck.geometry.triangles import box_pairs, pair_distances, triangle_distance
from meshcheck.results import Verdict
from meshcheck.verify.pair import solid_depth, surface_distance, verify_pair

CLEAR = Verdict.CLEAR

TOL = 1e-6


box = box_between  # boxes by their corners in this file


def unit(offset=(0, 0, 0)) -> trimesh.Trimesh:
    return box(np.asarray(offset, float), np.asarray(offset, float) + 1.0)


def cylinder(radius, z0, z1, sections=32) -> trimesh.Trimesh:
    c = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections)
    c.apply_translation([0, 0, 0.5 * (z0 + z1)])
    return c


def plate_with_hole(radius, sections=32) -> trimesh.Trimesh:
    return trimesh.boolean.difference(
        [box([-10, -10, 0], [10, 10, 10]), cylinder(radius, -1, 11, sections)], engine="manifold"
    )


def open_box(offset=(0, 0, 0)) -> trimesh.Trimesh:
    """A unit box with its top face removed: a surface that bounds no volume."""
    b = unit(offset)
    keep = ~np.isclose(b.triangles_center[:, 2], offset[2] + 1.0)
    return trimesh.Trimesh(b.vertices, b.faces[keep], process=False)


# --- known answers: solids ----------------------------------------------------------------------


def test_boxes_face_to_face_touch_at_distance_zero():
    v = verify_pair(unit(), unit((1, 0, 0)), tolerance=TOL, clearance=None)
    assert v.status == Verdict.TOUCHING
    assert v.distance == pytest.approx(0.0, abs=1e-12)
    assert v.depth is None and not v.is_surface_only
    assert v.location.lower[0] == pytest.approx(1.0, abs=1e-5)
    assert v.location.upper[0] == pytest.approx(1.0, abs=1e-5)


def test_boxes_offset_sideways_touch_on_the_shared_face_part():
    v = verify_pair(unit(), unit((1, 0.5, 0.25)), tolerance=TOL, clearance=0.1)
    assert v.status == Verdict.TOUCHING
    np.testing.assert_allclose(v.location.lower, [1, 0.5, 0.25], atol=1e-5)
    np.testing.assert_allclose(v.location.upper, [1, 1, 1], atol=1e-5)


def test_boxes_overlapping_by_0_3_interfere_with_exact_depth_and_volume():
    v = verify_pair(unit(), unit((0.7, 0, 0)), tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.distance == 0.0
    assert v.depth == pytest.approx(0.3, rel=1e-4)
    assert v.volume == pytest.approx(0.3, rel=1e-9)
    np.testing.assert_allclose(v.location.centroid, [0.85, 0.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(v.location.lower, [0.7, 0, 0], atol=1e-9)
    np.testing.assert_allclose(v.location.upper, [1, 1, 1], atol=1e-9)


def test_corner_overlap_depth_is_the_cube_side():
    v = verify_pair(unit(), unit((0.6, 0.6, 0.6)), tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.depth == pytest.approx(0.4, rel=1e-4)
    assert v.volume == pytest.approx(0.4**3, rel=1e-9)


def test_box_buried_in_box_interferes_with_the_inner_volume():
    outer, inner = box([0, 0, 0], [4, 4, 4]), box([1, 1, 1], [2, 3, 2.5])
    for a, b in ((outer, inner), (inner, outer)):
        v = verify_pair(a, b, tolerance=TOL, clearance=0.1)
        assert v.status == Verdict.INTERFERENCE
        assert v.volume == pytest.approx(1 * 2 * 1.5, rel=1e-9)
        assert v.depth == pytest.approx(1.0, rel=1e-3)


def test_surfaces_apart_finds_a_buried_part_and_clears_the_rest():
    outer, inner = box([0, 0, 0], [4, 4, 4]), box([1, 1, 1], [2, 2, 2])
    v = verify_pair(inner, outer, tolerance=TOL, clearance=None, surfaces_apart=True)
    assert v.status == Verdict.INTERFERENCE and v.volume == pytest.approx(1.0)
    far = box([10, 10, 10], [11, 11, 11])
    v = verify_pair(far, outer, tolerance=TOL, clearance=None, surfaces_apart=True)
    assert v.status == CLEAR


def test_inside_out_meshes_give_the_same_verdicts():
    outer, inner = box([0, 0, 0], [4, 4, 4]), box([1, 1, 1], [2, 2, 2])
    inner.invert()
    v = verify_pair(inner, outer, tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE and v.volume == pytest.approx(1.0)
    flipped = unit((0.7, 0, 0))
    flipped.invert()
    v = verify_pair(unit(), flipped, tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE and v.volume == pytest.approx(0.3)


def test_second_shell_buried_is_found():
    """A part made of two shells, one far away and one inside the other part."""
    two = trimesh.util.concatenate([box([10, 0, 0], [11, 1, 1]), box([1, 1, 1], [2, 2, 2])])
    v = verify_pair(two, box([0, 0, 0], [4, 4, 4]), tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.volume == pytest.approx(1.0)


def test_boxes_0_05_apart_are_a_clearance_finding_at_0_05():
    v = verify_pair(unit(), unit((1.05, 0.2, 0)), tolerance=TOL, clearance=0.1)
    assert v.status == Verdict.CLEARANCE
    assert v.distance == pytest.approx(0.05, abs=1e-12)
    assert v.location.lower[0] == pytest.approx(1.0)
    assert v.location.upper[0] == pytest.approx(1.05)
    assert verify_pair(unit(), unit((1.05, 0, 0)), tolerance=TOL, clearance=None).status == CLEAR
    assert verify_pair(unit(), unit((1.05, 0, 0)), tolerance=TOL, clearance=0.04).status == CLEAR


@pytest.mark.parametrize("shift", [-0.5e-6, 0.5e-6])
def test_overlap_or_gap_within_tolerance_is_touching(shift):
    v = verify_pair(unit(), unit((1 + shift, 0, 0)), tolerance=TOL, clearance=0.1)
    assert v.status == Verdict.TOUCHING
    assert v.distance == pytest.approx(max(shift, 0.0), abs=1e-12)


def test_block_in_l_bracket_corner_touches():
    bracket = trimesh.boolean.union(
        [box([0, 0, 0], [10, 5, 2]), box([8, 0, 2], [10, 5, 10])], engine="manifold"
    )
    v = verify_pair(bracket, box([4, 1, 2], [8, 4, 5]), tolerance=TOL, clearance=0.5)
    assert v.status == Verdict.TOUCHING
    np.testing.assert_allclose(v.location.lower, [4, 1, 2], atol=1e-5)
    np.testing.assert_allclose(v.location.upper, [8, 4, 5], atol=1e-5)


@pytest.mark.parametrize("sections", [16, 32])
def test_bolt_in_hole_distance_is_the_polygon_gap(sections):
    plate = plate_with_hole(3.1, sections)
    bolt = trimesh.boolean.union(
        [cylinder(3.0, -4, 10, sections), cylinder(5, 11, 14, sections)], engine="manifold"
    )
    v = verify_pair(plate, bolt, tolerance=1e-4, clearance=0.2)
    assert v.status == Verdict.CLEARANCE
    # Aligned regular polygons: the gap is the difference of the apothems (the boolean that made
    # the plate rounds its vertices to float32, hence 1e-6).
    assert v.distance == pytest.approx(0.1 * math.cos(math.pi / sections), abs=1e-6)


def test_oversized_bolt_depth_is_the_radial_excess():
    plate = plate_with_hole(3.0)
    v = verify_pair(plate, cylinder(3.2, -4, 14), tolerance=1e-4, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.depth == pytest.approx(0.2, rel=0.02)
    ring = math.pi * (3.2**2 - 3.0**2) * 10  # nominal circles; the polygons differ by ~0.6 %
    assert v.volume == pytest.approx(ring * math.sin(2 * math.pi / 32) / (2 * math.pi / 32))


@pytest.mark.parametrize("scale, offset", [(1.0, 1e5), (1e-3, 0.0), (1e-3, 100.0)])
def test_units_and_far_from_origin(scale, offset):
    def place(m):
        return m.copy().apply_scale(scale).apply_translation([offset, -offset, 2 * offset])

    tol = 1e-5 * scale
    touching = verify_pair(place(unit()), place(unit((1, 0, 0))), tolerance=tol, clearance=None)
    assert touching.status == Verdict.TOUCHING
    v = verify_pair(place(unit()), place(unit((0.7, 0, 0))), tolerance=tol, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.depth == pytest.approx(0.3 * scale, rel=1e-3)
    assert v.volume == pytest.approx(0.3 * scale**3, rel=1e-6)
    assert v.location.centroid[0] == pytest.approx(0.85 * scale + offset, abs=1e-6 * scale)
    v = verify_pair(place(unit()), place(unit((1.05, 0, 0))), tolerance=tol, clearance=0.1 * scale)
    assert v.status == Verdict.CLEARANCE
    assert v.distance == pytest.approx(0.05 * scale, rel=1e-6)


def test_solid_depth_of_a_slab_and_a_ball():
    slab = box([0, 0, 0], [5, 4, 0.25])
    assert solid_depth(slab.vertices, slab.faces) == pytest.approx(0.25, rel=1e-6)
    ball = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    ball.apply_transform(trimesh.transformations.euler_matrix(0.3, 0.2, 0.1))
    ball.apply_translation([1.0, -2.0, 0.5])
    # Oracle: the Chebyshev centre of the convex polytope, max r s.t. n_i . x + r <= h_i (an LP).
    n = ball.face_normals
    h = np.einsum("ij,ij->i", n, ball.triangles[:, 0])
    lp = linprog([0, 0, 0, -1], A_ub=np.c_[n, np.ones(len(n))], b_ub=h, bounds=[(None, None)] * 4)
    assert solid_depth(ball.vertices, ball.faces) == pytest.approx(-2 * lp.fun, rel=1e-3)


# --- known answers: surfaces that bound no volume ------------------------------------------------


def test_open_surface_crossing_a_box_interferes_surface_only():
    v = verify_pair(open_box(), unit((0.5, 0.3, 0.2)), tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.is_surface_only and v.volume is None and v.depth is None
    assert v.location is not None


def test_open_surface_resting_on_a_box_touches_surface_only():
    v = verify_pair(open_box((0, 0, 1)), unit((0.2, 0.1, 0)), tolerance=TOL, clearance=None)
    assert v.status == Verdict.TOUCHING
    assert v.is_surface_only


def test_open_surfaces_apart_are_clear_or_clearance():
    v = verify_pair(open_box(), open_box((1.02, 0, 0)), tolerance=TOL, clearance=0.05)
    assert v.status == Verdict.CLEARANCE and v.is_surface_only
    assert v.distance == pytest.approx(0.02)
    assert verify_pair(open_box(), open_box((1.2, 0, 0)), tolerance=TOL, clearance=0.05).status == (
        CLEAR
    )


def _open(m: trimesh.Trimesh, axis: int, side: int) -> trimesh.Trimesh:
    keep = ~np.isclose(m.triangles_center[:, axis], m.bounds[side][axis])
    return trimesh.Trimesh(m.vertices, m.faces[keep], process=False)


@pytest.mark.parametrize(
    "a, b, status",
    [
        # Surfaces that meet only along mesh edges and coplanar faces: no edge passes strictly
        # through a triangle, the probes inside the other mesh decide.
        (_open(unit(), 2, 1), unit((0.7, 0, 0)), Verdict.INTERFERENCE),
        (_open(unit(), 2, 1), _open(unit((0.7, 0, 0)), 2, 1), Verdict.INTERFERENCE),
        (_open(unit(), 0, 0), _open(unit((0.7, 0, 0)), 0, 1), Verdict.INTERFERENCE),
        (
            _open(box([0, 0, 0], [3, 3, 3]), 2, 1),
            _open(box([1, 1, 1], [2, 2, 2]), 2, 1),
            Verdict.INTERFERENCE,
        ),
        (_open(unit(), 2, 1), unit((1 - 1e-7, 0, 0)), Verdict.TOUCHING),
    ],
)
def test_open_surfaces_aligned_with_each_other(a, b, status):
    v = verify_pair(a, b, tolerance=TOL, clearance=None)
    assert v.status == status and v.is_surface_only


def test_box_buried_in_an_open_box_interferes():
    v = verify_pair(
        open_box(), box([0.3, 0.3, 0.2], [0.6, 0.6, 0.5]), tolerance=TOL, clearance=None
    )
    assert v.status == Verdict.INTERFERENCE and v.is_surface_only


# --- triangles -------------------------------------------------------------------------------


def _tri(t):
    return tuple(tuple(float(x) for x in p) for p in np.asarray(t))


def test_triangle_distance_known_answers():
    a = _tri([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    above = _tri([[0.2, 0.2, 0.5], [2, 2, 3], [0.3, 0.1, 4]])
    assert triangle_distance(*a, *above)[0] == pytest.approx(0.5)
    crossing = _tri([[0.2, 0.2, -1], [0.2, 0.2, 1], [3, 3, 0]])
    d, _, _, is_crossing = triangle_distance(*a, *crossing)
    assert d == 0.0 and is_crossing
    coplanar = _tri([[1, 1, 0], [2, 1, 0], [1, 2, 0]])
    assert triangle_distance(*a, *coplanar)[0] == pytest.approx(math.sqrt(0.5))
    edge_edge = _tri([[1, -1, 1], [1, 1, 1], [3, 0, 1]])
    # The segment x=1, z=1 vs the hypotenuse x+y=1, z=0: closest at (1,0,*), distance 1.
    assert triangle_distance(*a, *edge_edge)[0] == pytest.approx(1.0)


def _oracle_triangle_distance(ta, tb):
    """Minimise |sum(l_i a_i) - sum(m_j b_j)| over barycentric l, m (a convex QP) with SLSQP."""
    ta, tb = np.asarray(ta), np.asarray(tb)

    def f(x):
        d = x[:3] @ ta - x[3:] @ tb
        return d @ d

    best = np.inf
    for x0 in (np.full(6, 1 / 3), np.r_[1, 0, 0, 0, 1, 0], np.r_[0, 0, 1, 1, 0, 0]):
        r = minimize(
            f,
            x0,
            method="SLSQP",
            bounds=[(0, 1)] * 6,
            constraints=[
                {"type": "eq", "fun": lambda x: x[:3].sum() - 1},
                {"type": "eq", "fun": lambda x: x[3:].sum() - 1},
            ],
            options={"ftol": 1e-15, "maxiter": 500},
        )
        best = min(best, r.fun)
    return math.sqrt(max(best, 0.0))


coords = st.floats(-2, 2, allow_nan=False, allow_infinity=False)
triangles = st.lists(st.tuples(coords, coords, coords), min_size=3, max_size=3)


@settings(derandomize=True, deadline=None, max_examples=150)
@given(triangles, triangles)
def test_triangle_distance_matches_a_qp_oracle(ta, tb):
    ta, tb = np.asarray(ta), np.asarray(tb)
    area = lambda t: np.linalg.norm(np.cross(t[1] - t[0], t[2] - t[0]))  # noqa: E731
    assume(area(ta) >= 1e-3 and area(tb) >= 1e-3)
    d, pa, pb, _ = triangle_distance(*_tri(ta), *_tri(tb))
    oracle = _oracle_triangle_distance(ta, tb)
    # The kernel is exact; SLSQP's squared-distance accuracy limits the comparison near 0.
    assert d <= oracle + 1e-9
    assert d == pytest.approx(oracle, abs=1e-4)
    assert np.linalg.norm(np.subtract(pa, pb)) == pytest.approx(d, abs=1e-12)
    assert d == pytest.approx(triangle_distance(*_tri(tb), *_tri(ta))[0], abs=1e-12)


# --- meshes ----------------------------------------------------------------------------------


def _shape(kind: int) -> trimesh.Trimesh:
    if kind == 0:
        return trimesh.creation.icosphere(subdivisions=1, radius=0.6)
    if kind == 1:
        return trimesh.creation.box(extents=[1.0, 0.5, 0.8])
    return trimesh.creation.cylinder(radius=0.4, height=1.2, sections=12)


def _placed(kind, angles, offset):
    m = _shape(kind)
    m.apply_transform(trimesh.transformations.euler_matrix(*angles))
    m.apply_translation(offset)
    return m


angles = st.tuples(*[st.floats(0, 2 * math.pi)] * 3)
offsets = st.tuples(*[st.floats(-2, 2)] * 3)


def _brute_distance(a, b):
    pairs = np.stack(
        np.meshgrid(np.arange(len(a.faces)), np.arange(len(b.faces)), indexing="ij"), -1
    ).reshape(-1, 2)
    d, *_ = pair_distances(
        np.asarray(a.vertices, float),
        np.asarray(a.faces, np.int64),
        np.asarray(b.vertices, float),
        np.asarray(b.faces, np.int64),
        pairs.astype(np.int64),
    )
    return d.min()


@settings(derandomize=True, deadline=None, max_examples=60)
@given(st.integers(0, 2), st.integers(0, 2), angles, angles, offsets)
def test_mesh_distance_matches_brute_force_and_is_symmetric(ka, kb, ra, rb, off):
    a, b = _placed(ka, ra, (0, 0, 0)), _placed(kb, rb, off)
    v = verify_pair(a, b, tolerance=TOL, clearance=10.0)
    w = verify_pair(b, a, tolerance=TOL, clearance=10.0)
    brute = _brute_distance(a, b)
    assert v.status == w.status
    if brute > TOL:
        assert v.status in (Verdict.CLEARANCE, Verdict.INTERFERENCE)  # buried: interference
        if v.status == Verdict.CLEARANCE:
            assert v.distance == pytest.approx(brute, abs=1e-12)
            assert w.distance == pytest.approx(brute, abs=1e-12)
    else:
        assert v.status in (Verdict.TOUCHING, Verdict.INTERFERENCE)


@settings(derandomize=True, deadline=None, max_examples=60)
@given(st.integers(0, 2), st.integers(0, 2), angles, angles, offsets, st.floats(0.0, 1.5))
def test_surface_distance_with_enough_answers_as_the_least_distance(ka, kb, ra, rb, off, enough):
    """``enough`` stops at the first triangle pair within it: whether the surfaces come within
    ``enough``, and the exact distance when they do not, are those of every triangle pair
    (brute force)."""
    a, b = _placed(ka, ra, (0, 0, 0)), _placed(kb, rb, off)
    brute = _brute_distance(a, b)
    reach = 2.0
    got = surface_distance(a, b, reach=reach, enough=enough)
    full = surface_distance(a, b, reach=reach)
    assert (got <= enough) == (brute <= enough)
    if got > enough:
        assert got == full
        assert got == (pytest.approx(brute, abs=1e-12) if brute <= reach else math.inf) or (
            got == 0.0  # a shell of one inside the other
        )


@settings(derandomize=True, deadline=None, max_examples=40)
@given(st.integers(0, 2), st.integers(0, 2), angles, angles, offsets)
def test_mesh_distance_matches_fcl(ka, kb, ra, rb, off):
    a, b = _placed(ka, ra, (0, 0, 0)), _placed(kb, rb, off)
    is_hit = fcl_collide(a, b)
    v = verify_pair(a, b, tolerance=TOL, clearance=10.0)
    if is_hit:
        assert v.status in (Verdict.TOUCHING, Verdict.INTERFERENCE)
        return
    expected = fcl_distance(a, b)
    if v.status == Verdict.CLEARANCE:
        assert v.distance == pytest.approx(expected, abs=1e-6)
    else:  # fcl sees surfaces only: a part inside the other has a positive distance there
        assert v.status == Verdict.INTERFERENCE


@settings(derandomize=True, deadline=None, max_examples=40)
@given(st.integers(0, 2), st.integers(0, 2), angles, angles, offsets, angles, offsets)
def test_verdict_is_invariant_under_rigid_motion(ka, kb, ra, rb, off, rot, shift):
    a, b = _placed(ka, ra, (0, 0, 0)), _placed(kb, rb, off)
    motion = trimesh.transformations.euler_matrix(*rot)
    motion[:3, 3] = np.asarray(shift) * 100
    v = verify_pair(a, b, tolerance=TOL, clearance=0.5)
    w = verify_pair(
        a.copy().apply_transform(motion),
        b.copy().apply_transform(motion),
        tolerance=TOL,
        clearance=0.5,
    )
    assert v.status == w.status
    if v.status != CLEAR:
        assert v.distance == pytest.approx(w.distance, abs=1e-9)
    if v.volume is not None:
        assert w.volume == pytest.approx(v.volume, rel=1e-6)
        assert w.depth == pytest.approx(v.depth, rel=0.02)


def test_box_pairs_matches_all_pairs():
    rng = np.random.default_rng(0)
    alo = rng.uniform(0, 10, (300, 3))
    ahi = alo + rng.uniform(0, 1, (300, 3))
    blo = rng.uniform(0, 10, (200, 3))
    bhi = blo + rng.uniform(0, 1, (200, 3))
    got = {tuple(p) for p in box_pairs(alo, ahi, blo, bhi, 0.3).tolist()}
    gap_ok = np.all((alo[:, None] <= bhi[None] + 0.3) & (blo[None] <= ahi[:, None] + 0.3), axis=2)
    assert got == {tuple(p) for p in np.argwhere(gap_ok).tolist()}


# --- export ----------------------------------------------------------------------------------


def test_export_writes_parts_and_a_red_node_per_interference(tmp_path):
    from meshcheck.load import Body
    from meshcheck.reports.gltf import CLASH_COLOR, CLASHING_PART_COLOR, PART_COLOR, export_clashes

    a, b, c = unit(), unit((0.7, 0, 0)), unit((3, 0, 0))
    bodies = [Body(n, n, m) for n, m in (("a.stl", a), ("b.stl", b), ("c.stl", c))]
    v = verify_pair(a, b, tolerance=TOL, clearance=None)
    finding = results.Finding(a="a.stl", b="b.stl", verdict=v, id="0123456789ab")
    touching = results.Finding("b.stl", "c.stl", results.PairVerdict(Verdict.TOUCHING, 0.0))
    path = tmp_path / "clashes.glb"
    export_clashes(str(path), bodies, [finding, touching], units="m")

    scene = trimesh.load_scene(str(path))
    nodes = {n: scene.geometry[scene.graph[n][1]] for n in scene.graph.nodes_geometry}
    assert set(nodes) == {"a.stl", "b.stl", "c.stl", "interference a.stl x b.stl [0123456789ab]"}
    clash = nodes["interference a.stl x b.stl [0123456789ab]"]
    assert clash.volume == pytest.approx(0.3, rel=1e-6)
    colour = {n: tuple(int(x) for x in m.visual.material.baseColorFactor) for n, m in nodes.items()}
    assert colour["a.stl"] == colour["b.stl"] == CLASHING_PART_COLOR
    assert colour["c.stl"] == PART_COLOR
    assert colour["interference a.stl x b.stl [0123456789ab]"] == CLASH_COLOR


def test_export_marks_a_surface_only_clash_with_its_location_box(tmp_path):
    from meshcheck.load import Body
    from meshcheck.reports.gltf import export_clashes

    a, b = open_box(), unit((0.5, 0.3, 0.2))
    v = verify_pair(a, b, tolerance=TOL, clearance=None)
    assert v.is_surface_only
    assert v.solid is None  # nothing to draw but the location's box
    finding = results.Finding(a="a.obj", b="b.stl", verdict=v)
    path = tmp_path / "clashes.glb"
    bodies = [Body("a.obj", "a.obj", a), Body("b.stl", "b.stl", b)]
    export_clashes(str(path), bodies, [finding], units="m")
    scene = trimesh.load_scene(str(path))
    assert "interference a.obj x b.stl" in set(scene.graph.nodes_geometry)


@settings(derandomize=True, deadline=None, max_examples=40)
@given(angles, angles, st.tuples(*[st.floats(-0.9, 0.9)] * 3))
def test_depth_of_two_overlapping_boxes_matches_an_lp(ra, rb, off):
    """The shared solid of two boxes is convex: its inscribed ball is the Chebyshev centre of
    the twelve half-spaces, an LP independent of the mesh machinery."""
    a = _placed(1, ra, (0, 0, 0))
    b = _placed(1, rb, off)
    n = np.concatenate([a.face_normals, b.face_normals])
    h = np.einsum("ij,ij->i", n, np.concatenate([a.triangles[:, 0], b.triangles[:, 0]]))
    lp = linprog([0, 0, 0, -1], A_ub=np.c_[n, np.ones(len(n))], b_ub=h, bounds=[(None, None)] * 4)
    thickness = -2 * lp.fun
    assume(thickness > 1e-3)
    v = verify_pair(a, b, tolerance=TOL, clearance=None)
    assert v.status == Verdict.INTERFERENCE
    assert v.depth == pytest.approx(thickness, rel=1e-4)
