"""Point and ray queries through the BVH (``src/triangles.hpp``'s ``MeshBvh``) against answers
found without meshcheck: known distances and winding numbers of a cube, numpy brute forces over
every triangle (Ericson's closest point, Van Oosterom and Strackee's solid angle, Moller-Trumbore),
python-fcl's point distances, and half-spaces for which points a convex mesh holds. Many-point
distances also equal the one-point-at-a-time ones (below the BVH's threshold) bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import brute_point_distances, brute_winding_numbers, fcl_point_distances
from scipy.spatial import ConvexHull

from meshcheck.geometry.triangles import point_distances, ray_hits, winding_numbers

SETTINGS = settings(derandomize=True, deadline=None, max_examples=40)


def meshes():
    yield trimesh.creation.icosphere(3)
    yield trimesh.creation.box(extents=[5.0, 4.0, 0.25])
    yield trimesh.creation.annulus(1.0, 1.2, 0.3)
    yield trimesh.creation.cylinder(0.5, 3.0).apply_translation([1e4, -2e4, 3e3])


MESHES = list(meshes())
CUBE = trimesh.creation.box(extents=[2.0, 2.0, 2.0])  # faces in x, y, z = +-1


def arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def near(mesh, seed: int, count: int, spread: float = 1.0) -> np.ndarray:
    """``count`` points around the mesh, inside and out."""
    v = np.asarray(mesh.vertices)
    rng = np.random.default_rng(seed)
    return v.mean(axis=0) + rng.normal(size=(count, 3)) * spread * v.std(axis=0)


# --- known answers ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("point", "distance"),
    [
        ((3.0, 0.0, 0.0), 2.0),  # off a face
        ((2.0, 2.0, 0.0), np.sqrt(2.0)),  # off an edge
        ((2.0, -3.0, 4.0), np.sqrt(1.0 + 4.0 + 9.0)),  # off a corner
        ((0.0, 0.0, 0.0), 1.0),  # the centre: unsigned, to the nearest face
        ((0.25, 0.5, -0.1), 0.5),  # inside, nearest the +y face
        ((1.0, 0.3, 0.2), 0.0),  # on a face
    ],
)
def test_point_distances_to_a_cube_are_known(point, distance):
    got = point_distances(np.array([point]), *arrays(CUBE))
    assert got[0] == pytest.approx(distance, rel=1e-15, abs=1e-15)


def test_winding_numbers_of_a_cube_are_known():
    v, f = arrays(CUBE)
    points = np.array([[0.0, 0.0, 0.0], [0.9, -0.9, 0.5], [3.0, 0.0, 0.0], [0.0, 0.0, -5.0]])
    np.testing.assert_allclose(winding_numbers(points, v, f), [1, 1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(winding_numbers(points, v, f[:, ::-1]), [-1, -1, 0, 0], atol=1e-12)
    # from the centre each face (two triangles) subtends a sixth of the sphere
    top = np.flatnonzero(np.isclose(CUBE.triangles_center[:, 2], 1.0))
    assert len(top) == 2
    centre = np.zeros((1, 3))
    assert winding_numbers(centre, v, f[top])[0] == pytest.approx(1 / 6, abs=1e-12)
    open_box = np.delete(f, top, axis=0)
    assert winding_numbers(centre, v, open_box)[0] == pytest.approx(5 / 6, abs=1e-12)


# --- independent oracles ------------------------------------------------------------------------


@given(st.integers(0, len(MESHES) - 1), st.integers(0, 2**32 - 1), st.sampled_from([0.1, 1, 10]))
@SETTINGS
def test_point_distances_are_the_numpy_and_fcl_ones(which, seed, spread):
    mesh = MESHES[which]
    points = near(mesh, seed, 60, spread)
    got = point_distances(points, *arrays(mesh))
    # the re-centred coordinates of the far cylinder keep ~1e-16 of their 2e4
    tolerance = 1e-13 * (1.0 + np.abs(mesh.vertices).max())
    np.testing.assert_allclose(got, brute_point_distances(mesh, points), rtol=1e-12, atol=tolerance)
    np.testing.assert_allclose(got, fcl_point_distances(mesh, points), rtol=1e-9, atol=tolerance)


@given(st.integers(0, len(MESHES) - 1), st.integers(0, 2**32 - 1), st.booleans())
@SETTINGS
def test_winding_numbers_are_the_numpy_ones_on_closed_and_open_meshes(which, seed, is_open):
    mesh = MESHES[which]
    v, f = arrays(mesh)
    if is_open:  # a third of the faces gone: values between the integers
        f = f[np.random.default_rng(seed).random(len(f)) < 2 / 3]
    points = near(mesh, seed, 60)
    got = winding_numbers(points, v, f)
    expected = brute_winding_numbers(trimesh.Trimesh(v, f, process=False), points)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


@given(st.integers(0, 2**32 - 1))
@SETTINGS
def test_a_convex_mesh_holds_the_points_its_face_planes_hold(seed):
    rng = np.random.default_rng(seed)
    hull = ConvexHull(rng.normal(size=(30, 3)))
    mesh = trimesh.Trimesh(hull.points[hull.vertices], process=False).convex_hull
    points = rng.normal(size=(200, 3))
    plane = hull.equations[:, :3] @ points.T + hull.equations[:, 3:]  # (faces, points)
    margin = np.abs(plane).min(axis=0)
    clear = margin > 1e-9  # not on a face plane within rounding
    inside = (plane < 0).all(axis=0)
    got = winding_numbers(points, *arrays(mesh))
    np.testing.assert_allclose(got[clear], inside[clear].astype(float), atol=1e-9)


def brute_ray_hits(o, d, v, f, beyond):
    """First hit beyond ``beyond`` of each ray, every triangle tried (numpy)."""
    tri = v[f]
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    out = np.full(len(o), np.inf)
    for i in range(len(o)):
        h = np.cross(d[i], e2)
        det = (e1 * h).sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o[i] - a
            u = (s * h).sum(axis=1) * inv
            q = np.cross(s, e1)
            w = (d[i] * q).sum(axis=1) * inv
            t = (e2 * q).sum(axis=1) * inv
            ok = (det != 0) & (u >= 0) & (u <= 1) & (w >= 0) & (u + w <= 1) & (t > beyond)
        out[i] = t[ok].min() if ok.any() else np.inf
    return out


@given(st.integers(0, len(MESHES) - 1), st.integers(0, 2**32 - 1), st.sampled_from([0.1, 1, 10]))
@SETTINGS
def test_many_point_distances_are_the_single_point_ones(which, seed, spread):
    mesh = MESHES[which]
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)
    rng = np.random.default_rng(seed)
    points = v.mean(axis=0) + rng.normal(size=(50, 3)) * spread * v.std(axis=0)
    batch = point_distances(points, v, f)  # 50 points: through the BVH
    single = np.array([point_distances(p[None], v, f)[0] for p in points])  # every triangle
    assert batch.tobytes() == single.tobytes()


@given(st.integers(0, len(MESHES) - 1), st.integers(0, 2**32 - 1))
@SETTINGS
def test_ray_hits_are_the_brute_force_ones(which, seed):
    mesh = MESHES[which]
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64)
    rng = np.random.default_rng(seed)
    o = v.mean(axis=0) + rng.normal(size=(40, 3)) * v.std(axis=0)
    d = rng.normal(size=(40, 3)) * rng.choice([1e-3, 1.0, 50.0], size=(40, 1))
    d[0] = [0.0, 0.0, 1.0]  # axis-parallel: zero components in the slab test
    got = ray_hits(o, d, v, f, 1e-9)
    expected = brute_ray_hits(o, d, v, f, 1e-9)
    assert np.array_equal(np.isinf(got), np.isinf(expected))
    hit = np.isfinite(got)
    np.testing.assert_allclose(got[hit], expected[hit], rtol=1e-12)


def test_ray_from_inside_a_box_hits_its_far_wall():
    box = trimesh.creation.box(extents=[2.0, 2.0, 2.0])
    v, f = np.asarray(box.vertices), np.asarray(box.faces, dtype=np.int64)
    t = ray_hits(np.zeros((2, 3)), np.array([[1.0, 0, 0], [0, 0, -2.0]]), v, f, 0.0)
    assert t.tolist() == [1.0, 0.5]
    assert ray_hits(np.array([[5.0, 0, 0]]), np.array([[1.0, 0, 0]]), v, f, 0.0)[0] == np.inf


def test_ray_hits_rejects_mismatched_rays():
    box = trimesh.creation.box()
    with pytest.raises(ValueError):
        ray_hits(np.zeros((2, 3)), np.zeros((3, 3)), box.vertices, box.faces, 0.0)
