"""GJK / EPA on cases whose answer is known exactly (parry's ``epa3.rs`` style)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from meshcheck.geometry import (
    Status,
    concat_packs,
    intersects,
    pack_convex,
    query,
    query_pairs,
    repeat_pack,
    signed_distance,
)
from meshcheck.geometry.constants import HILL_CLIMB_MIN_VERTICES, PARALLEL_MIN_PAIRS

CUBE = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
CENTRED_CUBE = CUBE - 0.5


def vec(x, y, z) -> np.ndarray:
    return np.array([x, y, z], dtype=np.float64)


def box(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return lo + CUBE * (hi - lo)


def rotated(points, rotvec, about=None) -> np.ndarray:
    about = np.mean(points, axis=0) if about is None else np.asarray(about, float)
    return (points - about) @ Rotation.from_rotvec(rotvec).as_matrix().T + about


def assert_witnesses(c, a, b, *, atol):
    """point_b - point_a == distance * normal, the normal is unit, the plane separates."""
    assert np.linalg.norm(c.normal) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(c.point_b - c.point_a, c.distance * c.normal, atol=atol)
    if c.status == Status.SEPARATED:
        assert (a @ c.normal).max() <= c.point_a @ c.normal + atol
        assert (b @ c.normal).min() >= c.point_b @ c.normal - atol


# --- separated cubes -------------------------------------------------------------------------


@pytest.mark.parametrize("gap", [3.0, 1e-4, 1e8])
def test_cubes_apart_along_x(gap):
    c = query(CUBE, CUBE + vec(1.0 + gap, 0.0, 0.0))
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(gap, rel=1e-12)
    np.testing.assert_array_equal(c.normal, [1.0, 0.0, 0.0])
    assert c.point_a[0] == 1.0
    assert c.point_b[0] == pytest.approx(1.0 + gap, rel=1e-15)
    assert_witnesses(c, CUBE, CUBE + vec(1.0 + gap, 0, 0), atol=1e-12 * max(1.0, gap))


@pytest.mark.parametrize("gap", [3.0, 1e-4, 1e8])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rotated_cubes_apart(gap, seed):
    """The same pair, rotated rigidly as a whole: same distance, rotated normal."""
    rot = Rotation.random(random_state=seed)
    a = rot.apply(CUBE)
    b = rot.apply(CUBE + vec(1.0 + gap, 0.0, 0.0))
    c = query(a, b)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(gap, rel=1e-9, abs=1e-13)
    np.testing.assert_allclose(c.normal, rot.apply([1.0, 0.0, 0.0]), atol=1e-9)
    assert_witnesses(c, a, b, atol=1e-10 * max(1.0, gap))


def test_cube_corner_to_face():
    """A cube turned to present a corner to a face: the gap is the corner's height."""
    b = rotated(CENTRED_CUBE, [math.atan(1 / math.sqrt(2)), 0, 0])
    b = rotated(b, [0, 0, math.pi / 4])
    b = b + vec(0.5, 0.5, 1.25 - b[:, 2].min())
    c = query(CUBE, b)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(0.25, rel=1e-12)
    np.testing.assert_allclose(c.normal, [0, 0, 1], atol=1e-12)


# --- touching --------------------------------------------------------------------------------


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_face_touching_cubes(axis):
    shift = np.zeros(3)
    shift[axis] = 1.0
    c = query(CUBE, CUBE + shift)
    assert c.status == Status.TOUCHING
    assert abs(c.distance) <= 1e-10
    assert signed_distance(CUBE, CUBE + shift) == 0.0
    assert intersects(CUBE, CUBE + shift)
    assert abs(c.normal[axis]) == pytest.approx(1.0)


def test_face_touching_offset_cubes():
    """Touching faces that only partly overlap (and a shared edge, and a shared corner)."""
    for shift in ([1.0, 0.3, 0.6], [1.0, 1.0, 0.2], [1.0, 1.0, 1.0]):
        c = query(CUBE, CUBE + shift)
        assert c.status == Status.TOUCHING, shift
        assert signed_distance(CUBE, CUBE + shift) == 0.0


EDGE_DOWN = rotated(CENTRED_CUBE, [math.pi / 4, 0, 0])  # lowest edge parallel to x


@pytest.mark.parametrize("gap", [0.0, 1e-6, 0.1])
def test_cube_grazing_along_an_edge(gap):
    """A cube rotated 45 degrees about x rests its lowest edge on the top face of another."""
    b = EDGE_DOWN + vec(0.5, 0.5, 1.0 + gap - EDGE_DOWN[:, 2].min())
    c = query(CUBE, b)
    if gap == 0.0:
        assert c.status == Status.TOUCHING
        assert signed_distance(CUBE, b) == 0.0
        assert c.point_a[2] == pytest.approx(1.0, abs=1e-12)
    else:
        assert c.status == Status.SEPARATED
        assert c.distance == pytest.approx(gap, rel=1e-9)
        np.testing.assert_allclose(c.normal, [0, 0, 1], atol=1e-9)
        assert_witnesses(c, CUBE, b, atol=1e-12)


def test_edge_crossing_edge():
    """Two edges crossing at right angles, one above the other."""
    b = rotated(CENTRED_CUBE, [0, math.pi / 4, 0])  # lowest edge parallel to y
    a = EDGE_DOWN * [1, 1, -1]  # highest edge parallel to x, at z = +sqrt(2)/2
    h = a[:, 2].max()
    for gap in (0.0, 1e-7, 2.0):
        bb = b + vec(0, 0, h + gap - b[:, 2].min())
        c = query(a, bb)
        if gap == 0.0:
            assert c.status == Status.TOUCHING
        else:
            assert c.status == Status.SEPARATED
            assert c.distance == pytest.approx(gap, rel=1e-8)
            np.testing.assert_allclose(c.point_a, [0, 0, h], atol=1e-9)


@pytest.mark.parametrize("tilt", [1e-9, 1e-4, 0.1, 0.5])
@pytest.mark.parametrize("spin", [0.0, 0.3])
def test_cubes_touching_at_a_tilt(tilt, spin):
    """A cube tilted about x (then spun about z) lowered until it touches the face below.

    FCL's GJK aborts on nearly this pair; here every tilt gives touching at 0, a tiny gap gives
    that gap, and sinking the cube gives the sunk depth.
    """
    b = rotated(rotated(CENTRED_CUBE, [tilt, 0, 0]), [0, 0, spin])
    b = b + vec(0.5, 0.5, 1.0 - b[:, 2].min())
    assert query(CUBE, b).status == Status.TOUCHING
    assert signed_distance(CUBE, b) == 0.0
    up = query(CUBE, b + vec(0, 0, 1e-6))
    assert up.status == Status.SEPARATED
    assert up.distance == pytest.approx(1e-6, rel=1e-6)
    down = query(CUBE, b - vec(0, 0, 1e-3))
    assert down.status == Status.PENETRATING
    assert down.distance == pytest.approx(-1e-3, rel=1e-6)
    np.testing.assert_allclose(down.normal, [0, 0, 1], atol=1e-9)


def test_nearly_parallel_faces():
    """A face tilted by 1e-12 rad over another: the gap is the height of its lowest corner."""
    b = rotated(box([0, 0, 0], [1, 1, 1]), [1e-12, 0, 0], about=[0, 0, 0]) + vec(0, 0, 1 + 1e-6)
    c = query(CUBE, b)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(1e-6 + b[:, 2].min() - (1 + 1e-6), rel=1e-6)


# --- coplanar and flat inputs ----------------------------------------------------------------

TRI = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@pytest.mark.parametrize("gap", [1e-1, 1e-3, 1e-6, 1e-9])
def test_coplanar_triangles_vertex_to_vertex(gap):
    c = query(TRI, TRI + vec(1.0 + gap, 0.0, 0.0), tolerance=1e-13)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(gap, rel=1e-6)
    np.testing.assert_allclose(c.normal, [1, 0, 0], atol=1e-6)


@pytest.mark.parametrize("gap", [1e-1, 1e-3, 1e-6, 1e-9])
def test_coplanar_triangles_edge_to_edge(gap):
    """The mirror image across the hypotenuse, moved out by gap in the plane (openGJK's NaN)."""
    mirror = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    b = mirror + gap * np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    c = query(TRI, b, tolerance=1e-13)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(gap, rel=1e-6)
    np.testing.assert_allclose(c.normal, [1 / math.sqrt(2), 1 / math.sqrt(2), 0], atol=1e-6)
    assert np.isfinite(c.point_a).all() and np.isfinite(c.point_b).all()


def test_coplanar_overlapping_triangles_touch():
    """Flat shapes overlapping in their plane share no volume: touching, depth 0."""
    c = query(TRI, TRI + vec(0.2, 0.2, 0.0))
    assert c.status == Status.TOUCHING
    assert signed_distance(TRI, TRI + vec(0.2, 0.2, 0.0)) == 0.0


def test_parallel_triangles_stacked():
    c = query(TRI, TRI + vec(0.1, 0.1, 1e-9), tolerance=1e-13)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(1e-9, rel=1e-6)


# --- tetrahedra, points, segments ------------------------------------------------------------

TET = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])


@pytest.mark.parametrize("gap", [0.5, 1e-7])
def test_tetrahedron_vertex_below_face(gap):
    b = np.array([[0.2, 0.2, -gap], [-0.5, -0.5, -1], [1.5, 0, -1], [0, 1.5, -1]])
    c = query(TET, b)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(gap, rel=1e-9)
    np.testing.assert_allclose(c.point_a, [0.2, 0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(c.point_b, [0.2, 0.2, -gap], atol=1e-12)
    np.testing.assert_allclose(c.normal, [0, 0, -1], atol=1e-12)


def test_tetrahedra_slanted_face_distance():
    """The distance from the slanted face x + y + z = 1 to a point beyond it."""
    p = np.array([[1.0, 1.0, 1.0]])
    c = query(TET, p)
    assert c.distance == pytest.approx(2 / math.sqrt(3), rel=1e-12)
    np.testing.assert_allclose(c.point_a, [1 / 3, 1 / 3, 1 / 3], atol=1e-12)


def test_points():
    assert query([[0.0, 0, 0]], [[3.0, 4, 0]]).distance == pytest.approx(5.0, rel=1e-15)
    c = query([[1.0, 2, 3]], [[1.0, 2, 3]])
    assert c.status == Status.TOUCHING
    assert signed_distance([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]) == 0.0
    assert np.isfinite(c.normal).all()


def test_point_inside_cube_is_penetrating_by_nearest_face():
    c = query(CUBE, [[0.5, 0.5, 0.9]])
    assert c.status == Status.PENETRATING
    assert c.distance == pytest.approx(-0.1, rel=1e-12)
    np.testing.assert_allclose(c.normal, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(c.point_b, [0.5, 0.5, 0.9], atol=1e-12)


def test_point_on_cube_face_touches():
    assert query(CUBE, [[0.5, 0.5, 1.0]]).status == Status.TOUCHING
    assert query(CUBE, [[1.0, 1.0, 1.0]]).status == Status.TOUCHING


def test_skew_segments():
    a = np.array([[0.0, 0, 0], [1, 0, 0]])
    b = np.array([[0.5, -1, 1], [0.5, 1, 1]])
    c = query(a, b)
    assert c.distance == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(c.point_a, [0.5, 0, 0], atol=1e-15)
    np.testing.assert_allclose(c.point_b, [0.5, 0, 1], atol=1e-15)
    crossing = query(a, b - vec(0, 0, 1))
    assert crossing.status == Status.TOUCHING


def test_collinear_overlapping_segments_touch():
    a = np.array([[0.0, 0, 0], [1, 0, 0]])
    assert query(a, a + vec(0.5, 0, 0)).status == Status.TOUCHING
    c = query(a, a + vec(1.5, 0, 0))
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(0.5, rel=1e-15)


def test_segment_through_triangle_penetrates():
    """The least move that frees the segment is sideways to the triangle's nearest edge."""
    seg = np.array([[0.25, 0.25, -1.0], [0.25, 0.25, 1.0]])
    c = query(TRI, seg)
    assert c.status == Status.PENETRATING
    assert c.distance == pytest.approx(-0.25, rel=1e-9)


# --- overlapping boxes: exact depth and normal ----------------------------------------------


@pytest.mark.parametrize(
    ("lo", "hi", "depth", "normal"),
    [
        ([1.7, 0.2, 1.0], [3.0, 0.8, 2.0], 0.3, [1, 0, 0]),
        ([-1.0, 0.2, 1.0], [0.4, 0.8, 2.0], 0.4, [-1, 0, 0]),
        ([0.5, 0.9, 0.5], [1.5, 1.5, 1.5], 0.1, [0, 1, 0]),
        ([0.1, 0.1, -0.5], [1.9, 0.9, 0.05], 0.05, [0, 0, -1]),
    ],
)
def test_overlapping_boxes_depth_and_normal(lo, hi, depth, normal):
    a = box([0, 0, 0], [2, 1, 3])
    b = box(lo, hi)
    c = query(a, b)
    assert c.status == Status.PENETRATING
    assert c.distance == pytest.approx(-depth, rel=1e-9)
    np.testing.assert_allclose(c.normal, normal, atol=1e-9)
    assert_witnesses(c, a, b, atol=1e-9)
    # Moving B by the depth along the normal leaves the boxes touching.
    assert query(a, b + depth * np.asarray(normal)).status == Status.TOUCHING


def test_identical_cubes_penetrate_by_one():
    c = query(CUBE, CUBE)
    assert c.status == Status.PENETRATING
    assert c.distance == pytest.approx(-1.0, rel=1e-9)


def test_rotated_overlapping_cubes_depth_is_rotation_invariant():
    b = box([0.8, 0.1, 0.2], [1.8, 1.1, 1.2])
    base = query(CUBE, b)
    for seed in range(3):
        rot = Rotation.random(random_state=seed)
        c = query(rot.apply(CUBE), rot.apply(b))
        assert c.distance == pytest.approx(base.distance, rel=1e-9)
        np.testing.assert_allclose(c.normal, rot.apply(base.normal), atol=1e-9)


# --- far from the origin, tiny and huge ------------------------------------------------------


@pytest.mark.parametrize("size", [1e-3, 1.0, 1e4])
@pytest.mark.parametrize("offset", [0.0, 1e5, -1e5])
def test_scale_and_offset(size, offset):
    a = CUBE * size + offset
    ulp = np.spacing(abs(offset) + size)
    apart = query(a, a + vec(1.5 * size, 0, 0))
    assert apart.status == Status.SEPARATED
    assert apart.distance == pytest.approx(0.5 * size, abs=8 * ulp)
    assert_witnesses(apart, a, a + vec(1.5 * size, 0, 0), atol=8 * ulp)
    touching = query(a, a + vec(size, 0.3 * size, 0))
    assert touching.status == Status.TOUCHING
    sunk = query(a, a + vec(0.75 * size, 0.3 * size, 0.1 * size))
    assert sunk.status == Status.PENETRATING
    assert sunk.distance == pytest.approx(-0.25 * size, abs=8 * ulp)
    np.testing.assert_allclose(sunk.normal, [1, 0, 0], atol=1e-9)


def test_far_from_origin_small_gap():
    """1e5 from the origin, a 1e-6 gap between unit cubes keeps ~5 of its digits."""
    a = CUBE + 1e5
    c = query(a, a + vec(1.0 + 1e-6, 0, 0))
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(1e-6, rel=1e-4)


# --- duplicates, degenerate input, errors ----------------------------------------------------


def test_duplicate_and_interior_points_change_nothing():
    messy = np.concatenate([CUBE, CUBE, CUBE[::-1], [[0.5, 0.5, 0.5], [0.2, 0.3, 0.4]]])
    for shift, expected in (([3.0, 0, 0], 2.0), ([1.0, 0, 0], 0.0), ([0.75, 0, 0], -0.25)):
        assert signed_distance(messy, messy + shift) == pytest.approx(expected, abs=1e-12)
        assert signed_distance(CUBE, messy + shift) == pytest.approx(expected, abs=1e-12)


def test_all_points_coincident():
    a = np.repeat([[1.0, 1.0, 1.0]], 5, axis=0)
    assert query(a, CUBE + 2.0).distance == pytest.approx(math.sqrt(3.0), rel=1e-15)
    assert query(a, CUBE + 0.5).status == Status.PENETRATING


@pytest.mark.parametrize(
    "bad", [np.empty((0, 3)), np.ones((3, 2)), [[0.0, np.nan, 0.0]], [[np.inf, 0.0, 0.0]]]
)
def test_bad_input_is_a_value_error(bad):
    with pytest.raises(ValueError):
        query(bad, CUBE)
    with pytest.raises(ValueError):
        pack_convex([CUBE, bad])


def test_negative_tolerance_is_a_value_error():
    with pytest.raises(ValueError):
        query(CUBE, CUBE, tolerance=-1.0)


def test_tolerance_decides_touching():
    b = CUBE + vec(1.0 + 1e-6, 0, 0)
    assert query(CUBE, b, tolerance=1e-5).status == Status.TOUCHING
    assert signed_distance(CUBE, b, tolerance=1e-5) == 0.0
    assert query(CUBE, b, tolerance=1e-7).status == Status.SEPARATED
    sunk = CUBE + vec(1.0 - 1e-6, 0, 0)
    assert query(CUBE, sunk, tolerance=1e-5).status == Status.TOUCHING
    assert query(CUBE, sunk, tolerance=1e-7).status == Status.PENETRATING


def test_intersects():
    assert not intersects(CUBE, CUBE + 1.5)
    assert intersects(CUBE, CUBE + 0.5)
    assert intersects(CUBE, CUBE + 1.0)


# --- batch ------------------------------------------------------------------------------------


BIG = HILL_CLIMB_MIN_VERTICES + 50  # hulls this big are walked, not scanned


def sphere_points(n, seed, radius=1.0, centre=(0, 0, 0)):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    return radius * p / np.linalg.norm(p, axis=1, keepdims=True) + centre


def test_pack_convex_keeps_hull_vertices_and_adjacency():
    ball = sphere_points(BIG, 0)
    pack = pack_convex([ball, CUBE, TRI, [[1.0, 2.0, 3.0]]])
    assert pack.starts.tolist()[:2] == [0, BIG]  # all on the sphere: all hull vertices
    assert pack.starts[-1] == BIG + 8 + 3 + 1
    assert pack.nbr_starts[BIG] - pack.nbr_starts[0] >= 3 * BIG  # adjacency for the big hull
    assert pack.nbr_starts[BIG + 8] == pack.nbr_starts[BIG]  # the cube is scanned
    np.testing.assert_allclose(pack.lower[1], [0, 0, 0])
    np.testing.assert_allclose(pack.upper[0], ball.max(axis=0))
    inner = pack_convex([np.concatenate([CUBE, [[0.5, 0.5, 0.5]]] * 3)])
    assert inner.points.shape == (8, 3)


def test_concat_packs_offsets_indices():
    p1 = pack_convex([sphere_points(BIG, 1), CUBE])
    p2 = pack_convex([sphere_points(BIG, 2, centre=(3, 0, 0))])
    both = concat_packs([p1, p2])
    assert both.starts.tolist() == [0, BIG, BIG + 8, 2 * BIG + 8]
    assert both.nbrs[both.nbr_starts[BIG + 8] :].min() >= BIG + 8
    assert both.nbrs[: both.nbr_starts[BIG]].max() < BIG
    res = query_pairs(both, np.array([[0, 2], [1, 2]]), tolerance=1e-9)
    assert res.distance[0] == pytest.approx(1.0, abs=0.05)
    assert res.distance[1] == pytest.approx(signed_distance(CUBE, p2.points), rel=1e-12)


def test_repeat_pack_is_the_packs_of_its_copies_joined():
    """A pack moved to three placements: the same arrays as packing each moved copy and joining
    them, and GJK between copies measures the placements' offset."""
    pack = pack_convex([sphere_points(BIG, 1), CUBE])
    shifts = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [0.0, 7.0, 0.0]])
    moved = pack.points[None, :, :] + shifts[:, None, :]
    lower = pack.lower[None, :, :] + shifts[:, None, :]
    upper = pack.upper[None, :, :] + shifts[:, None, :]
    repeated = repeat_pack(pack, moved, lower, upper)
    one_by_one = concat_packs([pack._replace(points=p, lower=lo, upper=hi)
                               for p, lo, hi in zip(moved, lower, upper, strict=True)])  # fmt: skip
    for got, want in zip(repeated, one_by_one, strict=True):
        np.testing.assert_array_equal(got, want)
    res = query_pairs(repeated, np.array([[1, 3], [1, 5]]), tolerance=1e-9)  # cube to cube
    np.testing.assert_allclose(res.distance, [4.0, 6.0], atol=1e-12)


def test_query_pairs_matches_query_on_big_hulls():
    """Hill climbing over big hulls gives what a scan gives."""
    shapes = [sphere_points(BIG, s, centre=(1.9 * s, 0.3 * s, 0)) for s in range(5)]
    pack = pack_convex(shapes)
    pairs = np.array([[i, j] for i in range(5) for j in range(i + 1, 5)])
    res = query_pairs(pack, pairs, tolerance=1e-9)
    for row, (i, j) in enumerate(pairs):
        c = query(shapes[i], shapes[j], tolerance=1e-9)
        assert res.status[row] == c.status
        assert res.distance[row] == pytest.approx(c.distance, rel=1e-9, abs=1e-12)
        # any order works; the normal flips
        back = query_pairs(pack, np.array([[j, i]]), tolerance=1e-9)
        assert back.distance[0] == pytest.approx(c.distance, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(back.normal[0], -res.normal[row], atol=1e-6)


def test_query_pairs_depth_false_and_max_distance():
    pack = pack_convex([CUBE, CUBE + vec(0.6, 0, 0), CUBE + vec(1.0, 0, 0), CUBE + vec(10.0, 0, 0)])
    pairs = np.array([[0, 1], [0, 2], [0, 3]])
    full = query_pairs(pack, pairs, tolerance=1e-9)
    assert full.status.tolist() == [Status.PENETRATING, Status.TOUCHING, Status.SEPARATED]
    np.testing.assert_allclose(full.distance, [-0.4, 0.0, 9.0], atol=1e-12)
    quick = query_pairs(pack, pairs, tolerance=1e-9, depth=False, max_distance=0.5)
    assert quick.status.tolist() == full.status.tolist()
    assert -0.4 - 1e-12 <= quick.distance[0] < -1e-9  # minus a lower bound of the depth
    assert 0.5 < quick.distance[2] <= 9.0 + 1e-12  # a lower bound of the gap
    assert quick.status.dtype == np.int8
    empty = query_pairs(pack, np.empty((0, 2), np.int64), tolerance=1e-9)
    assert empty.distance.shape == (0,)
    with pytest.raises(ValueError):
        query_pairs(pack, np.array([[0, 4]]), tolerance=1e-9)


def test_query_pairs_per_pair_tolerance():
    pack = pack_convex([CUBE, CUBE + vec(1.0 + 1e-6, 0, 0)])
    pairs = np.array([[0, 1], [0, 1]])
    res = query_pairs(pack, pairs, tolerance=np.array([1e-5, 1e-7]))
    assert res.status.tolist() == [Status.TOUCHING, Status.SEPARATED]
    default = query_pairs(pack, pairs, tolerance=None)
    assert default.status.tolist() == [Status.SEPARATED] * 2


def test_query_pairs_threads_give_the_same_answers():
    rng = np.random.default_rng(7)
    shapes = [rng.normal(size=(12, 3)) * 0.4 + rng.uniform(-2, 2, size=3) for _ in range(40)]
    pack = pack_convex(shapes)
    pairs = np.array([[i, j] for i in range(40) for j in range(i + 1, 40)], dtype=np.int64)
    assert len(pairs) >= PARALLEL_MIN_PAIRS
    one = query_pairs(pack, pairs, tolerance=1e-9, threads=1)
    two = query_pairs(pack, pairs, tolerance=1e-9, threads=2)
    for got, want in zip(two, one, strict=True):
        np.testing.assert_array_equal(got, want)
    assert set(one.status.tolist()) >= {Status.SEPARATED, Status.PENETRATING}


def test_pack_convex_is_hull_skips_qhull_for_small_hulls():
    pack = pack_convex([CUBE, sphere_points(BIG, 3)], is_hull=True)
    assert pack.starts.tolist() == [0, 8, 8 + BIG]
    assert pack.nbr_starts[8] == pack.nbr_starts[0]  # the cube is scanned
    assert pack.nbr_starts[8 + BIG] > pack.nbr_starts[8]  # the big hull is walked
    res = query_pairs(pack, np.array([[0, 1]]), tolerance=1e-9)
    assert res.distance[0] == pytest.approx(signed_distance(CUBE, pack.points[8:]), rel=1e-12)


def test_read_only_and_strided_inputs():
    a = np.asfortranarray(CUBE)
    b = CUBE + vec(3.0, 0, 0)
    b.setflags(write=False)
    assert signed_distance(a, b) == pytest.approx(2.0, rel=1e-15)
    assert signed_distance(a[::2], b.tolist()) == pytest.approx(2.0, rel=1e-15)
    pack = pack_convex([a, b])
    pairs = np.array([[0, 1]])
    pairs.setflags(write=False)
    tol = np.array([1e-9])
    tol.setflags(write=False)
    assert query_pairs(pack, pairs, tolerance=tol).distance[0] == pytest.approx(2.0, rel=1e-15)


def test_scalar_results_are_python_types():
    assert type(intersects(CUBE, CUBE + 0.5)) is bool
    assert type(signed_distance(CUBE, CUBE + 3.0)) is float
    c = query(CUBE, CUBE + 3.0)
    assert type(c.distance) is float and isinstance(c.status, Status)
    assert c.point_a.dtype == np.float64 and c.point_a.shape == (3,)


def test_hill_climbing_on_a_cylinder_with_flat_caps():
    """Ties across a flat cap and along the side must not stop the walk short."""
    n = HILL_CLIMB_MIN_VERTICES // 2 + 20
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    cylinder = np.concatenate([ring, ring + vec(0, 0, 2.0)])
    cap_box = box([-0.2, -0.2, 2.0], [0.2, 0.2, 2.5])
    side_box = box([1.0, -0.1, 0.5], [1.5, 0.1, 1.5])
    apart = box([-0.2, -0.2, 2.5], [0.2, 0.2, 3.0])
    pack = pack_convex([cylinder, cap_box, side_box, apart])
    assert pack.nbr_starts[2 * n] > pack.nbr_starts[0]  # the cylinder is walked
    res = query_pairs(pack, np.array([[0, 1], [0, 2], [0, 3], [1, 0]]), tolerance=1e-9)
    touch, apart_ = Status.TOUCHING, Status.SEPARATED
    assert res.status.tolist() == [touch, touch, apart_, touch]
    assert res.distance[2] == pytest.approx(0.5, rel=1e-12)


def test_nearly_collinear_segments_1e10_apart():
    """A long thin Minkowski difference: the gap still gets a certified lower bound.

    (Found by hypothesis: with the search direction only ~3e-6 square to the segment, the
    bound from the far end was -2e-7 and the answer UNDECIDED.)
    """
    a = np.array([[0.1369616873214543, -0.2302132862361297, -0.4590264760638053],
                  [-0.4834723644714709, 0.3132702392002724, 0.4127555772777217]])  # fmt: skip
    b = a + vec(0.0, 0.0, 1e-10)
    e = a[1] - a[0]
    perp = np.linalg.norm(np.cross(e, [0.0, 0.0, 1e-10])) / np.linalg.norm(e)
    c = query(a, b, tolerance=1e-12)
    assert c.status == Status.SEPARATED
    assert c.distance == pytest.approx(perp, rel=1e-5)
    assert query(a, b).status == Status.TOUCHING  # default tolerance 1e-10 x size
