"""Write the end-to-end cases: ``tests/cases/<name>/`` with small binary STLs and ``expected.json``.

Run from the repository root: ``python tests/make_cases.py``. Units are millimetres.

The expected verdicts are computed here, independently of ``meshcheck.verify``, from the meshes
as written (reloaded from the STL, so float32 rounding is included):

- volumes: the shared height times the area common to the parts' cross-sections (shapely's
  GEOS), all of them prisms where they meet; never manifold3d, which ``verify.pair`` uses;
- distances: from the polygon geometry when it has a closed form (aligned regular polygons are
  ``(R - r) cos(pi / n)`` apart; a convex body in a convex cavity is ``min_i (h_i - max_v n_i . v)``
  from its walls), else python-fcl's mesh distance (an independent BVH implementation);
- depths: the thickness of the shared solid where it has a closed form, else not checked.

``expected.json``::

    {"description": str, "options": {"clearance": float | null},
     "findings": [{"a": file, "b": file, "status": str, "distance"?: float, "volume"?: float,
                   "depth"?: float}]}

Part pairs not listed must be clear. ``a < b`` by file name.
"""

from __future__ import annotations

import json
import math
import os
import shutil

import manifold3d
import numpy as np
import trimesh
from meshes import box_between, fcl_distance

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = os.path.join(HERE, "cases")
N = 24  # facets around every round part: small meshes keep CoACD fast


# --- shapes ---------------------------------------------------------------------------------


box = box_between  # boxes by their corners in this file


def cylinder(radius, z0, z1, x=0.0, y=0.0, sections=N) -> trimesh.Trimesh:
    c = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections)
    c.apply_translation([x, y, 0.5 * (z0 + z1)])
    return c


def union(*meshes) -> trimesh.Trimesh:
    return trimesh.boolean.union(list(meshes), engine="manifold")


def difference(*meshes) -> trimesh.Trimesh:
    return trimesh.boolean.difference(list(meshes), engine="manifold")


def gear(teeth: int, pitch: float, *, phase: float = 0.0, width: float = 0.5) -> trimesh.Trimesh:
    """A spur gear, 5 mm thick: trapezoid teeth between root and tip circles, ``width`` the
    tooth's angular width at the pitch circle as a fraction of the tooth pitch."""
    module = 2.0 * pitch / teeth
    root, tip = pitch - 1.25 * module, pitch + module
    step = 2.0 * math.pi / teeth
    points = []
    for k in range(teeth):
        c = phase + k * step
        for r, half in ((root, 0.32), (tip, 0.17), (tip, -0.17), (root, -0.32)):
            a = c - half * step * width / 0.5
            points.append((r * math.cos(a), r * math.sin(a)))
        gap = c + 0.5 * step
        points.append((root * math.cos(gap), root * math.sin(gap)))
    points.sort(key=lambda p: math.atan2(p[1], p[0]))
    solid = manifold3d.Manifold.extrude(manifold3d.CrossSection([points]), 5.0)
    mesh = solid.to_mesh()
    return trimesh.Trimesh(mesh.vert_properties[:, :3], mesh.tri_verts)


def torus(major, minor, sections=16, tube=8) -> trimesh.Trimesh:
    return trimesh.creation.torus(
        major_radius=major, minor_radius=minor, major_sections=sections, minor_sections=tube
    )


# --- truth ----------------------------------------------------------------------------------


def shared_volume(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Volume two parts share, for parts that are both prisms along z where their heights
    overlap (every case with a volume: bolts in plates, a pin in a wall, gears): the overlap's
    height times the area GEOS (shapely) finds common to their cross-sections. Independent of
    manifold3d, whose boolean ``verify.pair`` computes the volume with."""
    lo = max(a.bounds[0, 2], b.bounds[0, 2])
    hi = min(a.bounds[1, 2], b.bounds[1, 2])
    assert lo < hi, "the parts' heights do not overlap"
    for mesh in (a, b):
        z = mesh.triangles[..., 2]
        across = (z.min(axis=1) < hi) & (z.max(axis=1) > lo)
        # every face in the overlap is vertical: the cross-section is the same at every height
        assert np.abs(mesh.face_normals[across, 2]).max() < 1e-9
    height = 0.5 * (lo + hi)
    common = cross_section(a, height).intersection(cross_section(b, height))
    return float((hi - lo) * common.area)


def cross_section(mesh: trimesh.Trimesh, z: float):
    """The region a closed mesh cuts from the plane at height ``z``, as shapely geometry: the
    triangles' segments joined into closed rings, whose insides are combined even-odd (a hole's
    ring takes its inside away)."""
    import shapely

    v, f = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    assert np.abs(v[:, 2] - z).min() > 1e-9 * np.abs(v).max(), "a vertex lies in the plane"
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    below = v[:, 2] < z
    crossing = below[edges[:, 0]] != below[edges[:, 1]]
    # each crossing edge, lower index first, cut once: the triangles on either side of it
    # share the very same point, so the segments join exactly
    p, q = v[edges[:, 0]], v[edges[:, 1]]
    t = (z - p[:, 2]) / np.where(crossing, q[:, 2] - p[:, 2], 1.0)
    cut = p[:, :2] + t[:, None] * (q[:, :2] - p[:, :2])
    segments = cut.reshape(3, len(f), 2).transpose(1, 0, 2)[crossing.reshape(3, len(f)).T]
    segments = segments.reshape(-1, 2, 2)
    rings = shapely.line_merge(shapely.MultiLineString(list(segments)))
    rings = getattr(rings, "geoms", [rings])
    assert all(ring.is_ring for ring in rings), "the section is not closed rings"
    region = shapely.Polygon()
    for ring in rings:
        region = region.symmetric_difference(shapely.Polygon(ring))
    return region


# --- cases ----------------------------------------------------------------------------------


def bolts_in_plate():
    """Four plates 30 mm apart, each with a 3.3 mm hole; shanks 0.5, 0.1 and 0.02 smaller and one
    0.2 larger; heads 1 mm above the plates, so the radial gap is the closest approach.

    One plate per bolt: CoACD on a single plate with four holes takes over a minute.
    """
    hole = 3.3
    radii = {"0_5": 2.8, "0_1": 3.2, "0_02": 3.28, "oversized": 3.5}
    parts = {}
    for k, (tag, r) in enumerate(radii.items()):
        x = 30.0 * k
        parts[f"plate_{tag}.stl"] = difference(
            box([x - 8, -8, 0], [x + 8, 8, 10]), cylinder(hole, -1, 11, x)
        )
        parts[f"bolt_{tag}.stl"] = union(cylinder(r, -4, 11.5, x), cylinder(5.0, 11, 14, x))
    cos = math.cos(math.pi / N)
    findings = [
        {
            "a": "bolt_0_02.stl",
            "b": "plate_0_02.stl",
            "status": "clearance",
            "distance": (hole - 3.28) * cos,
        },
        {
            "a": "bolt_0_1.stl",
            "b": "plate_0_1.stl",
            "status": "clearance",
            "distance": (hole - 3.2) * cos,
        },
        {
            "a": "bolt_oversized.stl",
            "b": "plate_oversized.stl",
            "status": "interference",
            "depth": (3.5 - hole) * cos,
            "volume": ("bolt_oversized.stl", "plate_oversized.stl"),
        },
    ]
    return (
        parts,
        {"clearance": 0.2},
        findings,
        "bolts in holes: radial gaps 0.5, 0.1, 0.02 and -0.2",
    )


def pin_in_housing():
    """A pin buried in the thick wall of an L-shaped housing, no surfaces crossing."""
    housing = union(box([0, 0, 0], [30, 20, 6]), box([0, 0, 6], [8, 20, 30]))
    pin = cylinder(1.5, 10, 22, 4.0, 10.0)
    findings = [
        {
            "a": "housing.stl",
            "b": "pin.stl",
            "status": "interference",
            "depth": 3.0 * math.cos(math.pi / N),
            "volume": ("housing.stl", "pin.stl"),
        }
    ]
    return (
        {"housing.stl": housing, "pin.stl": pin},
        {"clearance": None},
        findings,
        "a pin buried inside a non-convex housing",
    )


def chain_links():
    """Two torus links through each other's holes, not touching: a clearance finding."""
    a = torus(3.0, 0.9)
    b = torus(3.0, 0.9)
    b.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    b.apply_translation([3.0, 0, 0])
    return (
        {"link_a.stl": a, "link_b.stl": b},
        {"clearance": 1.5},
        [{"a": "link_a.stl", "b": "link_b.stl", "status": "clearance", "distance": "fcl"}],
        "linked chain rings that do not touch",
    )


def ball_in_cup():
    """A ball floating in a cup's cavity: inside the cup's hull, outside its solid."""
    cup = difference(cylinder(5.0, 0, 9), cylinder(4.0, 1, 10))
    ball = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    ball.apply_translation([0.3, -0.2, 4.0])
    return (
        {"cup.stl": cup, "ball.stl": ball},
        {"clearance": 1.5},
        [{"a": "ball.stl", "b": "cup.stl", "status": "clearance", "distance": "cavity"}],
        "a ball floating in a cup's cavity",
    )


def block_in_bracket():
    bracket = union(box([0, 0, 0], [20, 10, 3]), box([17, 0, 3], [20, 10, 20]))
    block = box([9, 2, 3], [17, 8, 9])
    return (
        {"bracket.stl": bracket, "block.stl": block},
        {"clearance": 0.5},
        [{"a": "block.stl", "b": "bracket.stl", "status": "touching", "distance": 0.0}],
        "a block tucked into an L-bracket's inner corner",
    )


def blocks_face_to_face():
    return (
        {"left.stl": box([0, 0, 0], [10, 10, 10]), "right.stl": box([10, 3, 2], [16, 8, 7])},
        {"clearance": None},
        [{"a": "left.stl", "b": "right.stl", "status": "touching", "distance": 0.0}],
        "blocks face to face",
    )


def gears_backlash():
    a = gear(10, 10.0)
    b = gear(10, 10.0, phase=math.pi / 10, width=0.4)
    b.apply_translation([20.0, 0, 0])
    return (
        {"gear_a.stl": a, "gear_b.stl": b},
        {"clearance": 0.3},
        [{"a": "gear_a.stl", "b": "gear_b.stl", "status": "clearance", "distance": "fcl"}],
        "gears meshing with backlash",
    )


def gears_too_close():
    a = gear(10, 10.0)
    b = gear(10, 10.0, phase=math.pi / 10, width=0.4)
    b.apply_translation([19.0, 0, 0])
    return (
        {"gear_a.stl": a, "gear_b.stl": b},
        {"clearance": 0.3},
        [
            {
                "a": "gear_a.stl",
                "b": "gear_b.stl",
                "status": "interference",
                "volume": ("gear_a.stl", "gear_b.stl"),
            }
        ],
        "gears set too close",
    )


def shaft_in_tilted_bearing():
    """A shaft in a bearing bore, 0.05 radial gap, on an axis tilted 35 degrees, 100 mm out."""
    bearing = difference(cylinder(6.0, 0, 5), cylinder(3.05, -1, 6))
    shaft = cylinder(3.0, -10, 15)
    move = trimesh.transformations.rotation_matrix(math.radians(35), [1, 1, 0.3])
    move[:3, 3] = [100.0, -50.0, 20.0]
    for m in (bearing, shaft):
        m.apply_transform(move)
    return (
        {"bearing.stl": bearing, "shaft.stl": shaft},
        {"clearance": 0.1},
        [
            {
                "a": "bearing.stl",
                "b": "shaft.stl",
                "status": "clearance",
                "distance": 0.05 * math.cos(math.pi / N),
            }
        ],
        "a shaft in a bearing bore on a tilted axis",
    )


CASE_BUILDERS = {
    "bolts_in_plate": bolts_in_plate,
    "pin_in_housing": pin_in_housing,
    "chain_links": chain_links,
    "ball_in_cup": ball_in_cup,
    "block_in_bracket": block_in_bracket,
    "blocks_face_to_face": blocks_face_to_face,
    "gears_backlash": gears_backlash,
    "gears_too_close": gears_too_close,
    "shaft_in_tilted_bearing": shaft_in_tilted_bearing,
}


def _cavity_distance(ball: trimesh.Trimesh, cup: trimesh.Trimesh) -> float:
    """Distance from a convex body to the walls of the cup's convex cavity (its floor and the
    inward-facing side facets): min over wall planes of h - max_v n . v."""
    n, centers = cup.face_normals, cup.triangles_center
    radial = np.hypot(centers[:, 0], centers[:, 1])
    toward_axis = np.einsum("ij,ij->i", n[:, :2], centers[:, :2]) < 0
    walls = (toward_axis & (radial < 4.5)) | (np.isclose(centers[:, 2], 1.0) & (n[:, 2] > 0.9))
    # The cavity is the intersection of the half-spaces behind the walls (normals into it).
    h = -np.einsum("ij,ij->i", n[walls], cup.triangles[walls, 0])
    reach = (-n[walls] @ ball.vertices.T).max(axis=1)
    return float((h - reach).min())


def main() -> None:
    if os.path.isdir(CASES):
        shutil.rmtree(CASES)
    for name, build in CASE_BUILDERS.items():
        parts, options, findings, description = build()
        folder = os.path.join(CASES, name)
        os.makedirs(folder)
        written = {}
        for file, mesh in parts.items():
            assert mesh.is_watertight, (name, file)
            path = os.path.join(folder, file)
            mesh.export(path)
            written[file] = trimesh.load_mesh(path)
        for f in findings:
            if isinstance(f.get("volume"), tuple):
                f["volume"] = shared_volume(*(written[p] for p in f["volume"]))
            if f.get("distance") == "fcl":
                f["distance"] = fcl_distance(written[f["a"]], written[f["b"]])
            elif f.get("distance") == "cavity":
                f["distance"] = _cavity_distance(written["ball.stl"], written["cup.stl"])
        doc = {"description": description, "options": options, "findings": findings}
        with open(os.path.join(folder, "expected.json"), "w") as fh:
            json.dump(doc, fh, indent=2)
            fh.write("\n")
        sizes = ", ".join(f"{k} {len(m.faces)}" for k, m in written.items())
        print(f"{name}: {sizes}")


if __name__ == "__main__":
    main()
