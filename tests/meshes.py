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


def fcl_point_distances(mesh: trimesh.Trimesh, points) -> np.ndarray:
    """FCL's distance from each point (a sphere of radius 0) to the mesh's triangles."""
    import fcl

    surface = fcl_object(mesh)
    request = fcl.DistanceRequest()
    return np.array(
        [
            fcl.distance(surface, fcl.CollisionObject(fcl.Sphere(0.0), fcl.Transform(p)), request)
            for p in np.atleast_2d(np.asarray(points, float))
        ]
    )


def brute_point_distances(mesh: trimesh.Trimesh, points, chunk: int = 64) -> np.ndarray:
    """Distance from each point to the nearest of every triangle, in numpy: the closest point on
    each triangle by its Voronoi regions (Ericson, Real-Time Collision Detection, 5.1.5)."""
    tri = np.asarray(mesh.vertices, float)[np.asarray(mesh.faces)]
    a, b, c = (tri[None, :, k] for k in range(3))
    ab, ac, bc = b - a, c - a, c - b
    points = np.atleast_2d(np.asarray(points, float))
    out = []
    for start in range(0, len(points), chunk):
        p = points[start : start + chunk, None, :]
        ap, bp, cp = p - a, p - b, p - c
        d1, d2 = _dot(ab, ap), _dot(ac, ap)
        d3, d4 = _dot(ab, bp), _dot(ac, bp)
        d5, d6 = _dot(ab, cp), _dot(ac, cp)
        va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
        with np.errstate(divide="ignore", invalid="ignore"):
            regions = [  # first match wins, in Ericson's order
                ((d1 <= 0) & (d2 <= 0), a),
                ((d3 >= 0) & (d4 <= d3), b),
                ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + (d1 / (d1 - d3))[..., None] * ab),
                ((d6 >= 0) & (d5 <= d6), c),
                ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + (d2 / (d2 - d6))[..., None] * ac),
                (
                    (va <= 0) & (d4 >= d3) & (d5 >= d6),
                    b + ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[..., None] * bc,
                ),
            ]
            total = va + vb + vc
            closest = a + (vb / total)[..., None] * ab + (vc / total)[..., None] * ac
        for mask, point in reversed(regions):
            closest = np.where(mask[..., None], np.broadcast_to(point, closest.shape), closest)
        out.append(np.linalg.norm(p - closest, axis=-1).min(axis=1))
    return np.concatenate(out)


def _dot(x, y):
    return np.einsum("...i,...i->...", x, y)


def brute_winding_numbers(mesh: trimesh.Trimesh, points, chunk: int = 256) -> np.ndarray:
    """Generalized winding number of each point, in numpy: the triangles' solid angles (Van
    Oosterom and Strackee) summed over ``4 pi`` (1 inside a closed outward mesh, 0 outside)."""
    tri = np.asarray(mesh.vertices, float)[np.asarray(mesh.faces)]
    points = np.atleast_2d(np.asarray(points, float))
    out = []
    for start in range(0, len(points), chunk):
        p = points[start : start + chunk, None, :]
        a, b, c = (tri[None, :, k] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = _dot(a, np.cross(b, c))
        den = la * lb * lc + _dot(a, b) * lc + _dot(b, c) * la + _dot(c, a) * lb
        out.append(np.arctan2(det, den).sum(axis=1) / (2 * np.pi))
    return np.concatenate(out)


def winding_inside(mesh: trimesh.Trimesh, points) -> np.ndarray:
    """Which ``points`` lie inside a closed mesh, by the generalized winding number: an oracle
    needing no ray library."""
    return np.abs(brute_winding_numbers(mesh, points)) > 0.5


def gltf_document(meshes: dict, nodes: list[dict], roots: list[int] | None = None) -> dict:
    """A glTF document of ``meshes`` (name -> trimesh.Trimesh, float32 positions, data embedded
    as a base64 URI) placed by ``nodes``: each node's ``"mesh"`` names a mesh; its other keys
    (``name``, ``translation``, ``rotation``, ``scale``, ``matrix``, ``children``) are glTF's.
    ``roots`` default: every node no other node lists as a child."""
    import base64

    names = list(meshes)
    data, views, accessors, gltf_meshes = b"", [], [], []
    for k, name in enumerate(names):
        v = np.asarray(meshes[name].vertices, dtype=np.float32)
        f = np.asarray(meshes[name].faces, dtype=np.uint32)
        for array in (v, f.ravel()):
            views.append({"buffer": 0, "byteOffset": len(data), "byteLength": array.nbytes})
            data += array.tobytes()
        accessors.append({
            "bufferView": 2 * k, "componentType": 5126, "count": len(v), "type": "VEC3",
            "min": v.min(axis=0).tolist(), "max": v.max(axis=0).tolist(),
        })  # fmt: skip
        accessors.append(
            {"bufferView": 2 * k + 1, "componentType": 5125, "count": f.size, "type": "SCALAR"}
        )
        primitive = {"attributes": {"POSITION": 2 * k}, "indices": 2 * k + 1}
        gltf_meshes.append({"name": name, "primitives": [primitive]})
    out_nodes = [
        {**{k: v for k, v in node.items() if k != "mesh"},
         **({"mesh": names.index(node["mesh"])} if "mesh" in node else {})}
        for node in nodes
    ]  # fmt: skip
    if roots is None:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [k for k in range(len(nodes)) if k not in children]
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": out_nodes,
        "meshes": gltf_meshes,
        "buffers": [{"byteLength": len(data), "uri": uri}],
        "bufferViews": views,
        "accessors": accessors,
    }


def matrix_node(transform, **node) -> dict:
    """A glTF node placed by a 4 x 4 ``transform`` (column-major ``matrix``)."""
    return {**node, "matrix": np.asarray(transform, dtype=np.float64).T.ravel().tolist()}


def chain_urdf(count: int, *, box: str = "0.06 0.02 0.02", limit: float = 0.5) -> str:
    """A URDF of ``count`` links in a row, each a box centred 0.05 m along its frame's x axis,
    joined by revolute joints about z every 0.1 m with the range ``-limit..limit`` (radians)."""
    geometry = f'<origin xyz="0.05 0 0"/><geometry><box size="{box}"/></geometry>'
    links = [f'<link name="l{k}"><collision>{geometry}</collision></link>' for k in range(count)]
    joints = [
        f'<joint name="j{k}" type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/>'
        f'<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="{-limit}" upper="{limit}"/>'
        "</joint>"
        for k in range(1, count)
    ]
    return "\n".join(['<robot name="chain">', *links, *joints, "</robot>"])
