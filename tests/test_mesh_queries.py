"""Point and ray queries through the BVH (``src/triangles.hpp``'s ``MeshBvh``) give the
brute-force answers, bit for bit: many-point distances against one point at a time (below the
BVH's threshold), rays against a numpy Moller-Trumbore over every triangle."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.geometry.triangles import point_distances, ray_hits

SETTINGS = settings(derandomize=True, deadline=None, max_examples=40)


def meshes():
    yield trimesh.creation.icosphere(3)
    yield trimesh.creation.box(extents=[5.0, 4.0, 0.25])
    yield trimesh.creation.annulus(1.0, 1.2, 0.3)
    yield trimesh.creation.cylinder(0.5, 3.0).apply_translation([1e4, -2e4, 3e3])


MESHES = list(meshes())


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
