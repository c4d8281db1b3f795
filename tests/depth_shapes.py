"""Part pairs whose interference depth is known in closed form, for tests/test_depth.py and
bench/depth.py. Each builder returns ``(a, b, depth)``: two closed meshes and the diameter of the
largest ball inside their shared solid, computed for the faceted geometry (not the circles the
facets approximate).

The faceted answers: between two aligned regular ``n``-gons whose vertices lie on one ray (half
angle ``alpha = pi / n``), the largest circle sits on that ray, touching the inner polygon's vertex
and the outer polygon's two facets beside it: radius ``w cos(alpha) / (1 + cos(alpha))`` for a
radial width ``w`` between the vertices. Convex shared solids (lens, wedge) are checked against a
linear program over their faces in the tests instead.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh


def prism_tube(r_in, r_out, z0, z1, n):
    """A tube with ``n`` flat facets inside and out, vertices at angles ``2 pi k / n``; float64
    exact (no boolean)."""
    t = 2.0 * math.pi * np.arange(n) / n
    ring = np.c_[np.cos(t), np.sin(t)]
    v = np.concatenate(
        [
            np.c_[r_in * ring, np.full(n, z0)],
            np.c_[r_out * ring, np.full(n, z0)],
            np.c_[r_in * ring, np.full(n, z1)],
            np.c_[r_out * ring, np.full(n, z1)],
        ]
    )
    k = np.arange(n)
    j = (k + 1) % n
    ib, ob, it, ot = k, n + k, 2 * n + k, 3 * n + k
    jb, jo, jt, jot = j, n + j, 2 * n + j, 3 * n + j
    faces = np.concatenate(
        [
            np.c_[ob, jot, ot],
            np.c_[ob, jo, jot],  # outer wall, normal outward
            np.c_[ib, it, jt],
            np.c_[ib, jt, jb],  # inner wall, normal toward the axis
            np.c_[ib, jb, jo],
            np.c_[ib, jo, ob],  # bottom
            np.c_[it, ot, jot],
            np.c_[it, jot, jt],  # top
        ]
    )
    mesh = trimesh.Trimesh(v, faces, process=False)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def pin(radius, z0, z1, n, offset=0.0):
    m = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=n)
    return m.apply_translation([offset, 0.0, 0.5 * (z0 + z1)])


def _corner_ball(width, n):
    c = math.cos(math.pi / n)
    return 2.0 * width * c / (1.0 + c)


def annulus(scale=1.0, e=0.05, n=64):
    """A pin of radius ``1 + e`` in a hole of radius 1 through a plate 1 thick: an annular
    shell ``e`` thick."""
    plate = prism_tube(1.0, 3.0, 0.0, 1.0, n)
    shaft = pin(1.0 + e, -0.5, 1.5, n)
    return plate.apply_scale(scale), shaft.apply_scale(scale), scale * _corner_ball(e, n)


def crescent(scale=1.0, offset=0.05, n=64):
    """A pin of the hole's radius, moved ``offset`` sideways: a crescent ``offset`` thick."""
    plate = prism_tube(1.0, 3.0, 0.0, 1.0, n)
    shaft = pin(1.0, -0.5, 1.5, n, offset=offset)
    return plate.apply_scale(scale), shaft.apply_scale(scale), scale * _corner_ball(offset, n)


def lens(scale=1.0, overlap=0.02, count=64):
    """Two spheres (radii 1 and 0.7) pole to pole, overlapping by ``overlap`` on the axis; the
    depth is below ``overlap`` by the facets' tilt (the tests compute it with an LP)."""
    a = trimesh.creation.uv_sphere(radius=1.0, count=[count, count])
    b = trimesh.creation.uv_sphere(radius=0.7, count=[count, count])
    b.apply_translation([0.0, 0.0, 1.7 - overlap])
    return a.apply_scale(scale), b.apply_scale(scale), None


def wedge(scale=1.0, press=0.05, half_angle=math.pi / 6):
    """A wedge (edge along y, half angle ``half_angle``) pressed ``press`` into a block's top:
    the shared solid is a prism over an isosceles triangle, depth = its inscribed circle."""
    block = trimesh.creation.box(extents=[2.0, 2.0, 1.0]).apply_translation([0, 0, -0.5])
    h = 0.5
    w = h * math.tan(half_angle)
    # The wedge's edge runs along y at z = -press; its faces open upward by +-half_angle.
    profile = [(0.0, -press), (w, h - press), (-w, h - press)]
    corners = [(x, y, z) for x, z in profile for y in (-0.5, 0.5)]
    prism = trimesh.convex.convex_hull(np.array(corners))
    s = math.sin(half_angle)
    return block.apply_scale(scale), prism.apply_scale(scale), scale * 2 * press * s / (1 + s)


def tilted_slab_pair(scale=1.0, overlap=0.001):
    """Two unit cubes, the second moved ``1 - overlap`` along a tilted axis and both turned the
    same way: the shared solid is a tilted slab ``overlap`` thick."""
    turn = trimesh.transformations.euler_matrix(0.4, 0.3, 0.2)
    a = trimesh.creation.box(extents=[1, 1, 1])
    b = trimesh.creation.box(extents=[1, 1, 1]).apply_translation([1.0 - overlap, 0.0, 0.0])
    for m in (a, b):
        m.apply_transform(turn)
        m.apply_scale(scale)
    return a, b, scale * overlap
