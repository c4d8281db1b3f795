"""Mesh builders and the FCL oracle shared by the tests (and tests/make_cases.py)."""

from __future__ import annotations

import numpy as np
import trimesh


def box(extents=(1.0, 1.0, 1.0), at=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    """An axis-aligned box of ``extents`` centred at ``at``."""
    return trimesh.creation.box(extents=extents).apply_translation(at)


def box_between(lower, upper) -> trimesh.Trimesh:
    """The axis-aligned box from corner ``lower`` to corner ``upper``."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    return box(upper - lower, 0.5 * (lower + upper))


def fcl_object(mesh: trimesh.Trimesh):
    """A python-fcl collision object of a mesh's triangles (an independent oracle)."""
    import fcl

    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


def fcl_collide(a: trimesh.Trimesh, b: trimesh.Trimesh) -> bool:
    """True when FCL finds the two surfaces in contact."""
    import fcl

    request, result = fcl.CollisionRequest(), fcl.CollisionResult()
    return fcl.collide(fcl_object(a), fcl_object(b), request, result) > 0


def fcl_distance(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """FCL's distance between the two surfaces."""
    import fcl

    request = fcl.DistanceRequest(enable_nearest_points=True)
    return float(fcl.distance(fcl_object(a), fcl_object(b), request, fcl.DistanceResult()))


def winding_inside(mesh: trimesh.Trimesh, points) -> np.ndarray:
    """Which ``points`` lie inside a closed mesh, by the generalized winding number (the sum of
    the triangles' solid angles, Van Oosterom and Strackee): an oracle needing no ray library."""
    tri = np.asarray(mesh.vertices, float)[np.asarray(mesh.faces)]
    out = []
    for p in np.atleast_2d(np.asarray(points, float)):
        a, b, c = (tri[:, k] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
        den += np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb
        out.append(abs(np.arctan2(det, den).sum() / (2 * np.pi)) > 0.5)
    return np.array(out)
