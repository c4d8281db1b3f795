"""Loading: part names, multi-body files, --split, directories, and one-line input errors."""

from __future__ import annotations

import base64
import json
import os
import struct
import zipfile

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import box

from meshcheck.errors import InputError, MeshcheckWarning
from meshcheck.load import expand_paths, load_bodies, split_shells
from meshcheck.verify.shells import warn_overlapping_shells

HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=40)


def write_stl(path, mesh) -> str:
    mesh.export(str(path))
    return str(path)


def write_gltf(path, nodes) -> str:
    """A .gltf with one unit-cube mesh used by every node in ``nodes`` (name, translation)."""
    cube = box()
    v = np.asarray(cube.vertices, dtype=np.float32)
    f = np.asarray(cube.faces, dtype=np.uint32)
    data = v.tobytes() + f.tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": [{"name": n, "mesh": 0, "translation": list(t)} for n, t in nodes],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [
            {
                "byteLength": len(data),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
            }
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": v.nbytes},
            {"buffer": 0, "byteOffset": v.nbytes, "byteLength": f.nbytes},
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": len(v),
                "type": "VEC3",
                "min": v.min(axis=0).tolist(),
                "max": v.max(axis=0).tolist(),
            },
            {"bufferView": 1, "componentType": 5125, "count": f.size, "type": "SCALAR"},
        ],
    }
    path.write_text(json.dumps(doc))
    return str(path)


def write_3mf(path, items) -> str:
    """A .3mf with one unit cube object placed by each build item (name, translation)."""
    cube = box()
    verts = "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in cube.vertices)
    tris = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in cube.faces)
    objects, build = [], []
    for k, (name, (x, y, z)) in enumerate(items, start=1):
        objects.append(
            f'<object id="{k}" name="{name}" type="model"><components>'
            f'<component objectid="100"/></components></object>'
        )
        build.append(f'<item objectid="{k}" transform="1 0 0 0 1 0 0 0 1 {x} {y} {z}"/>')
    model = (
        '<?xml version="1.0" encoding="UTF-8"?>'
        '<model unit="millimeter" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        f'<resources><object id="100" name="cube" type="model"><mesh><vertices>{verts}</vertices>'
        f"<triangles>{tris}</triangles></mesh></object>{''.join(objects)}</resources>"
        f"<build>{''.join(build)}</build></model>"
    )
    rels = (
        '<?xml version="1.0" encoding="UTF-8"?>'
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
        '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
        'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>'
    )
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("_rels/.rels", rels)
        z.writestr("3D/3dmodel.model", model)
    return str(path)


# ------------------------------------------------------------------------------------------
# Known answers


def test_single_body_file_is_named_by_its_path(tmp_path):
    path = write_stl(tmp_path / "cube.stl", box())
    (body,) = load_bodies([path])
    assert body.name == path
    assert body.path == path
    assert len(body.mesh.faces) == 12
    assert body.is_closed
    np.testing.assert_array_equal(body.transform, np.eye(4))


def test_gltf_instances_share_the_mesh_and_keep_their_placement(tmp_path):
    path = write_gltf(tmp_path / "assy.gltf", [("right", (5, 0, 0)), ("left", (0, 0, 0))])
    bodies = load_bodies([path])
    assert [b.name for b in bodies] == [f"{path}#left", f"{path}#right"]
    left, right = bodies
    assert left.mesh is right.mesh  # one decomposition serves both instances
    assert left.digest == right.digest
    np.testing.assert_allclose(right.transform[:3, 3], [5, 0, 0])
    np.testing.assert_allclose(right.world.bounds, [[4.5, -0.5, -0.5], [5.5, 0.5, 0.5]])


def test_glb_bodies_are_named_by_node(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(box(), node_name="frame", geom_name="frame")
    scene.add_geometry(box(at=(3, 0, 0)), node_name="pin", geom_name="pin")
    path = str(tmp_path / "assy.glb")
    scene.export(path)
    assert [b.name for b in load_bodies([path])] == [f"{path}#frame", f"{path}#pin"]


def write_two_cube_obj(path, keyword: str):
    """An OBJ file of two cubes, 3 apart, as objects (``o``) or groups (``g``) housing and lid."""
    lines = []
    for k, name in enumerate(["housing", "lid"]):
        lines.append(f"{keyword} {name}")
        cube = box(at=(3 * k, 0, 0))
        lines += [f"v {x} {y} {z}" for x, y, z in cube.vertices]
        lines += [f"f {a + 1 + 8 * k} {b + 1 + 8 * k} {c + 1 + 8 * k}" for a, b, c in cube.faces]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("keyword", ["o", "g"])
def test_obj_objects_and_groups_are_bodies(tmp_path, keyword):
    path = write_two_cube_obj(tmp_path / "assy.obj", keyword)
    bodies = load_bodies([str(path)])
    assert [b.name for b in bodies] == [f"{path}#housing", f"{path}#lid"]
    assert all(b.is_closed and len(b.mesh.faces) == 12 for b in bodies)


def _obj_cubes(offsets, indexing) -> str:
    """An OBJ of unit cubes (``o cube<k>``) at ``offsets``; each object's faces index its own
    vertices by ``indexing(k, i)`` for the 0-based vertex ``i`` of cube ``k``."""
    cube = box(extents=(1, 1, 1))
    lines = []
    for k, offset in enumerate(offsets):
        lines.append(f"o cube{k}")
        lines += [f"v {x} {y} {z}" for x, y, z in cube.vertices + offset]
        lines += ["f " + " ".join(indexing(k, i) for i in face) for face in cube.faces]
    return "\n".join(lines) + "\n"


RELATIVE = {
    "absolute": lambda k, i: str(8 * k + i + 1),
    "relative": lambda k, i: str(i - 8),
    "mixed": lambda k, i: str(i - 8) if (i + k) % 2 else str(8 * k + i + 1),
    "mixed with slashes": lambda k, i: f"{i - 8}//" if i % 3 else f"{8 * k + i + 1}//",
}


@pytest.mark.parametrize("indexing", sorted(RELATIVE))
def test_obj_relative_indices_count_back_from_the_vertices_read_so_far(tmp_path, indexing):
    offsets = np.array([[0, 0, 0], [0.5, 0.2, 0.1], [2.0, 0.0, 0.0]])
    path = tmp_path / "cubes.obj"
    path.write_text(_obj_cubes(offsets, RELATIVE[indexing]))
    bodies = load_bodies([str(path)])
    assert [b.name for b in bodies] == [f"{path}#cube{k}" for k in range(3)]
    for body, offset in zip(bodies, offsets, strict=True):
        assert body.is_closed
        np.testing.assert_allclose(body.world.bounds, [offset - 0.5, offset + 0.5])


def test_obj_relative_index_before_the_first_vertex_is_one_line(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 -2 -1\n")
    with pytest.raises(InputError, match=r"line 4: index -4 reaches before the first vertex"):
        load_bodies([str(path)])


def test_3mf_build_items_are_placed_bodies(tmp_path):
    path = write_3mf(tmp_path / "assy.3mf", [("base", (0, 0, 0)), ("top", (0, 0, 2))])
    bodies = load_bodies([path])
    assert [b.name for b in bodies] == [f"{path}#base/cube", f"{path}#top/cube"]
    assert bodies[0].mesh is bodies[1].mesh
    np.testing.assert_allclose(bodies[1].world.bounds, [[-0.5, -0.5, 1.5], [0.5, 0.5, 2.5]])


def _3mf_with_model(path, model: str) -> str:
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("3D/3dmodel.model", model)
    return str(path)


def _3mf_model(objects: str, build: str) -> str:
    return (
        '<model xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        f"<resources>{objects}</resources><build>{build}</build></model>"
    )


def test_3mf_transform_is_row_vector_convention(tmp_path):
    bar = box((2, 1, 1))
    verts = "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in bar.vertices)
    tris = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in bar.faces)
    mesh = f"<mesh><vertices>{verts}</vertices><triangles>{tris}</triangles></mesh>"
    obj = f'<object id="7">{mesh}</object>'
    # 90 degrees about z, then 10 along x: the bar's long axis turns to y
    item = '<item objectid="7" transform="0 1 0 -1 0 0 0 0 1 10 0 0"/>'
    path = _3mf_with_model(tmp_path / "bar.3mf", _3mf_model(obj, item))
    (body,) = load_bodies([path])
    assert body.name == path
    np.testing.assert_allclose(body.world.bounds, [[9.5, -1, -0.5], [10.5, 1, 0.5]], atol=1e-12)


@pytest.mark.parametrize(
    ("build", "reason"),
    [
        ('<item objectid="9"/>', "missing object 9"),
        ('<item objectid="1" transform="1 0 0"/>', "malformed 3MF transform"),
        ("", "holds no triangles"),
    ],
)
def test_broken_3mf_is_an_input_error(tmp_path, build, reason):
    obj = '<object id="1"><mesh><vertices><vertex x="0" y="0" z="0"/></vertices></mesh></object>'
    path = _3mf_with_model(tmp_path / "broken.3mf", _3mf_model(obj, build))
    with pytest.raises(InputError, match=reason):
        load_bodies([path])


def test_3mf_component_cycle_is_an_input_error(tmp_path):
    obj = '<object id="1"><components><component objectid="1"/></components></object>'
    path = _3mf_with_model(tmp_path / "cycle.3mf", _3mf_model(obj, '<item objectid="1"/>'))
    with pytest.raises(InputError, match="form a cycle through object 1"):
        load_bodies([path])


def test_directory_expands_to_sorted_mesh_files(tmp_path):
    root = tmp_path / "assy"
    (root / "sub").mkdir(parents=True)
    (root / ".hidden").mkdir()
    write_stl(root / "b.stl", box())
    write_stl(root / "sub" / "a.stl", box(at=(3, 0, 0)))
    write_stl(root / "A.STL", box(at=(6, 0, 0)))
    write_stl(root / ".hidden" / "c.stl", box())
    (root / "notes.txt").write_text("not a mesh")
    arg = str(root)
    assert expand_paths([arg]) == [
        os.path.join(arg, "A.STL"),
        os.path.join(arg, "b.stl"),
        os.path.join(arg, "sub", "a.stl"),
    ]
    assert [b.name for b in load_bodies([arg])] == expand_paths([arg])


def test_split_gives_a_part_per_shell_and_keeps_cavities(tmp_path):
    hollow, cavity = box((4, 4, 4)), box((2, 2, 2))
    cavity.invert()  # inward-facing lining of the hollow's cavity
    cube = box(at=(10, 0, 0))
    path = write_stl(tmp_path / "shells.stl", trimesh.util.concatenate([cube, hollow, cavity]))
    (whole,) = load_bodies([path])
    parts = load_bodies([path], split=True)
    assert [p.name for p in parts] == [f"{path}#1", f"{path}#2"]
    assert [len(p.mesh.faces) for p in parts] == [12, 24]
    assert parts[0].world.bounds[0][0] == pytest.approx(9.5)
    assert parts[1].mesh.volume == pytest.approx(64 - 8)
    assert len(whole.mesh.faces) == 36


def test_split_keeps_a_single_shell_whole(tmp_path):
    path = write_stl(tmp_path / "one.stl", box())
    assert [b.name for b in load_bodies([path], split=True)] == [path]


def test_split_leaves_a_solid_inside_a_cavity_its_own_part():
    hollow, cavity, ball = box((6, 6, 6)), box((4, 4, 4)), box((1, 1, 1))
    cavity.invert()
    shells = split_shells(trimesh.util.concatenate([ball, hollow, cavity]))
    assert [round(float(s.volume), 6) for s in shells] == [1.0, 216.0 - 64.0]


def test_degenerate_triangles_are_dropped_with_a_warning(tmp_path):
    cube = box()
    faces = np.vstack([cube.faces, [[0, 0, 1], [0, 1, 1]]])
    path = str(tmp_path / "degenerate.ply")
    trimesh.Trimesh(cube.vertices, faces, process=False).export(path)
    with pytest.warns(MeshcheckWarning, match=r"degenerate\.ply: dropped 2 degenerate"):
        (body,) = load_bodies([path])
    assert len(body.mesh.faces) == 12
    assert body.is_closed


def test_open_mesh_loads_with_a_warning(tmp_path):
    cube = box()
    path = str(tmp_path / "open.stl")
    trimesh.Trimesh(cube.vertices, cube.faces[:-1], process=False).export(path)
    with pytest.warns(MeshcheckWarning, match=r"open\.stl: mesh is not closed"):
        (body,) = load_bodies([path])
    assert not body.is_closed


# ------------------------------------------------------------------------------------------
# Broken inputs: one InputError naming the path


def _binary_stl(count: int, triangles: int | None = None) -> bytes:
    triangles = count if triangles is None else triangles
    return b"\0" * 80 + struct.pack("<I", count) + b"\0" * (50 * triangles)


BROKEN = {
    "missing.stl": (None, "no such file"),
    "empty.stl": (b"", "empty file"),
    "short.stl": (b"abc", "84-byte header"),
    "truncated.stl": (_binary_stl(12)[:-20], "header says 12 triangles"),
    "huge.stl": (_binary_stl(4_000_000_000, 2), "header says 4000000000 triangles"),
    "garbage.stl": (bytes(range(256)) * 7, "binary STL"),
    "ascii_garbage.stl": (b"solid x\n this is not a facet\nendsolid x\n", "no triangles"),
    "zero.stl": (_binary_stl(0), "no triangles"),
    "notes.xyz": (b"1 2 3\n", "unsupported file type .xyz"),
    "noext": (b"1 2 3\n", "unsupported file type"),
    "cloud.ply": (
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
        "point cloud",
    ),
    "nan.obj": (b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "NaN or infinite"),
    "inf.obj": (b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", "NaN or infinite"),
    "garbage.glb": (b"glTF" + bytes(range(200)), "cannot be read"),
    "garbage.3mf": (b"PK not really a zip", "cannot be read as 3MF"),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_broken_input_is_one_input_error_naming_the_file(tmp_path, name):
    content, reason = BROKEN[name]
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(InputError) as info:
        load_bodies([str(path)])
    assert info.value.path == str(path)
    assert reason in info.value.reason
    assert "\n" not in str(info.value)


def test_nan_in_binary_stl_is_an_input_error(tmp_path):
    cube = box()
    v = cube.vertices.copy()
    v[3] = [np.nan, 0, 0]
    path = write_stl(tmp_path / "nan.stl", trimesh.Trimesh(v, cube.faces, process=False))
    with pytest.raises(InputError, match="NaN or infinite"):
        load_bodies([path])


def test_directory_without_meshes_is_an_input_error(tmp_path):
    (tmp_path / "readme.txt").write_text("nothing here")
    with pytest.raises(InputError, match="holds no mesh files") as info:
        load_bodies([str(tmp_path)])
    assert info.value.path == str(tmp_path)


def test_the_same_part_twice_is_an_input_error(tmp_path):
    path = write_stl(tmp_path / "cube.stl", box())
    with pytest.raises(InputError, match="given more than once"):
        load_bodies([path, path])


# ------------------------------------------------------------------------------------------
# Properties


@HYPOTHESIS
@given(cut=st.integers(min_value=1, max_value=12 * 50 + 83))
def test_any_truncated_binary_stl_is_an_input_error(tmp_path_factory, cut):
    data = box().export(file_type="stl")
    path = tmp_path_factory.mktemp("cut") / "cut.stl"
    path.write_bytes(data[:-cut])
    with pytest.raises(InputError, match=r"cut\.stl"):
        load_bodies([str(path)])


@HYPOTHESIS
@given(
    order=st.permutations(range(4)),
    gaps=st.lists(st.floats(0.1, 5.0), min_size=4, max_size=4),
)
def test_split_finds_every_disjoint_shell_in_file_order(order, gaps):
    xs = np.cumsum([1.0 + g for g in gaps])
    sizes = [1.0, 0.5, 0.8, 0.3]
    cubes = [box((sizes[k],) * 3, at=(xs[k], 0, 0)) for k in order]
    shells = split_shells(trimesh.util.concatenate(cubes))
    assert len(shells) == 4
    got = [float(s.volume) for s in shells]
    np.testing.assert_allclose(got, [sizes[k] ** 3 for k in order], rtol=1e-9)


# ------------------------------------------------------------------------------------------
# Names: a function of the files alone, the same in every process


def _two_primitive_gltf(path) -> str:
    """A glTF whose one node has no name and a mesh of two primitives (as CesiumMilkTruck)."""
    doc = json.loads(open(write_gltf(path, [("x", (0, 0, 0))])).read())
    del doc["nodes"][0]["name"]
    prim = doc["meshes"][0]["primitives"][0]
    doc["meshes"][0]["primitives"] = [prim, dict(prim)]
    path.write_text(json.dumps(doc))
    return str(path)


NAMES_SCRIPT = """
import json, sys
from meshcheck.load import load_bodies
out = {}
for arg in sys.argv[1:]:
    split = arg.startswith("split:")
    path = arg.removeprefix("split:")
    out[arg] = [b.name for b in load_bodies([path], split=split)]
print(json.dumps(out))
"""


def test_names_are_the_same_in_every_process(tmp_path):
    import subprocess
    import sys

    gltf = _two_primitive_gltf(tmp_path / "truck.gltf")
    threemf = write_3mf(tmp_path / "assy.3mf", [("base", (0, 0, 0)), ("base", (0, 0, 2))])
    obj = write_two_cube_obj(tmp_path / "groups.obj", "g")
    solid = box().export(file_type="stl_ascii")
    stl = tmp_path / "solids.stl"
    stl.write_text(solid.replace("solid", "solid top", 1) + solid + solid)
    shells = write_stl(
        tmp_path / "shells.stl", trimesh.util.concatenate([box(), box(at=(3, 0, 0))])
    )
    args = [gltf, threemf, str(obj), str(stl), f"split:{shells}"]
    runs = []
    for seed in ("1", "2", "12345"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        proc = subprocess.run(
            [sys.executable, "-c", NAMES_SCRIPT, *args],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
            check=True,
        )
        runs.append(json.loads(proc.stdout))
    assert runs[0] == runs[1] == runs[2]
    names = runs[0]
    assert names[gltf] == [f"{gltf}#0/0", f"{gltf}#0/1"]
    assert names[threemf] == [f"{threemf}#base/cube", f"{threemf}#base/cube_2"]
    assert names[str(obj)] == [f"{obj}#housing", f"{obj}#lid"]
    assert names[str(stl)] == [f"{stl}#geometry_1", f"{stl}#geometry_2", f"{stl}#top"]
    assert names[f"split:{shells}"] == [f"{shells}#1", f"{shells}#2"]


def test_relative_names_are_relative_to_the_argument(tmp_path):
    root = tmp_path / "assy"
    (root / "sub").mkdir(parents=True)
    write_stl(root / "sub" / "a.stl", box())
    gltf = write_gltf(tmp_path / "two.gltf", [("left", (0, 0, 0)), ("right", (3, 0, 0))])
    bodies = load_bodies([str(root), gltf], units="m")  # both files in metres
    assert [b.name for b in bodies] == [
        os.path.join(str(root), "sub", "a.stl"),
        f"{gltf}#left",
        f"{gltf}#right",
    ]
    assert [b.relative_name for b in bodies] == [
        os.path.join("sub", "a.stl"),
        "two.gltf#left",
        "two.gltf#right",
    ]
    split = load_bodies([str(root)], split=True)
    assert [b.relative_name for b in split] == [os.path.join("sub", "a.stl")]


# ------------------------------------------------------------------------------------------
# Closedness on the mesh as given


def _t_vertex_box(extents) -> trimesh.Trimesh:
    """A closed box with one edge split by its midpoint on one side only, stitched by a
    zero-area triangle (a, b, midpoint): closed, but holding a triangle of no area."""
    cube = box(extents)
    v, f = cube.vertices.copy(), cube.faces.copy()
    a, b, c = f[0]
    m = len(v)
    v = np.vstack([v, 0.5 * (v[a] + v[b])])
    faces = np.vstack([[[a, m, c], [m, b, c]], f[1:], [[a, b, m]]])
    return trimesh.Trimesh(v, faces, process=False)


def test_a_zero_area_triangle_that_closes_the_surface_is_kept(tmp_path):
    mesh = _t_vertex_box((4, 4, 4))
    assert mesh.area == pytest.approx(96.0)
    path = write_stl(tmp_path / "t.stl", mesh)
    (body,) = load_bodies([path])  # no warning: filterwarnings = error
    assert body.is_closed
    assert len(body.mesh.faces) == 14
    assert float(body.mesh.volume) == pytest.approx(64.0)


@pytest.mark.parametrize("at", [(0.5, 0.0, 0.0), (1.8, 0.3, 0.0)], ids=["buried", "crossing"])
def test_t_vertex_mesh_gives_the_clean_meshs_verdict_depth_and_volume(tmp_path, at):
    import meshcheck

    probe = write_stl(tmp_path / "probe.stl", box((1, 1, 1), at=at))
    results = []
    for name, mesh in [("clean.stl", box((4, 4, 4))), ("t.stl", _t_vertex_box((4, 4, 4)))]:
        big = write_stl(tmp_path / name, mesh)
        result = meshcheck.check([big, probe])
        (finding,) = result.findings
        results.append(finding)
    clean, t = results
    assert (t.status, t.is_surface_only) == (clean.status, clean.is_surface_only)
    assert (clean.status, clean.is_surface_only) == ("interference", False)
    assert t.depth == pytest.approx(clean.depth, rel=1e-9)
    assert t.volume == pytest.approx(clean.volume, rel=1e-9)
    assert clean.volume == pytest.approx(1.0 if at[0] == 0.5 else 0.7, rel=1e-6)


# ------------------------------------------------------------------------------------------
# Units


def test_gltf_metres_are_converted_to_the_mm_of_an_stl_beside_it(tmp_path):
    stl = write_stl(tmp_path / "frame.stl", box((1000, 1000, 1000)))  # mm, no unit declared
    gltf = write_gltf(tmp_path / "pin.gltf", [("pin", (2, 0, 0))])  # a 1 m cube 2 m away
    frame, pin = load_bodies([stl, gltf])
    assert frame.units == pin.units == "mm"
    np.testing.assert_allclose(pin.world.bounds, [[1500, -500, -500], [2500, 500, 500]])
    np.testing.assert_allclose(pin.mesh.bounds, [[-0.5] * 3, [0.5] * 3])  # local: the file's


def test_files_that_all_declare_one_unit_are_reported_in_it(tmp_path):
    gltf = write_gltf(tmp_path / "a.gltf", [("a", (0, 0, 0)), ("b", (2, 0, 0))])
    bodies = load_bodies([gltf])
    assert {b.units for b in bodies} == {"m"}
    np.testing.assert_array_equal(bodies[1].transform[:3, :3], np.eye(3))


def test_3mf_unit_attribute_is_read(tmp_path):
    obj = f'<object id="1">{_3mf_mesh(box())}</object>'
    model = _3mf_model(obj, '<item objectid="1"/>').replace("<model ", '<model unit="inch" ', 1)
    path = _3mf_with_model(tmp_path / "inch.3mf", model)
    (alone,) = load_bodies([path])
    assert alone.units == "in"
    np.testing.assert_allclose(alone.world.extents, [1, 1, 1])
    stl = write_stl(tmp_path / "mm.stl", box((25.4, 25.4, 25.4), at=(100, 0, 0)))
    inch, mm = load_bodies([path, stl])
    assert inch.units == mm.units == "mm"
    np.testing.assert_allclose(inch.world.extents, [25.4] * 3)


def test_units_name_the_undeclared_files_and_the_report(tmp_path):
    stl = write_stl(tmp_path / "frame.stl", box((40, 40, 40)))  # inches
    gltf = write_gltf(tmp_path / "pin.gltf", [("pin", (0, 0, 0))])  # 1 m = 39.37 in
    frame, pin = load_bodies([stl, gltf], units="inch")
    assert frame.units == pin.units == "in"
    np.testing.assert_allclose(frame.world.extents, [40] * 3)
    np.testing.assert_allclose(pin.world.extents, [1 / 0.0254] * 3)


def test_unknown_units_are_a_config_error(tmp_path):
    from meshcheck.errors import ConfigError

    stl = write_stl(tmp_path / "a.stl", box())
    with pytest.raises(ConfigError, match="unknown length unit 'furlong'"):
        load_bodies([stl], units="furlong")


def test_parts_a_thousand_times_apart_in_size_warn_of_mixed_units(tmp_path):
    mm = write_stl(tmp_path / "frame_mm.stl", box((400, 400, 400)))
    # 0.1 m in metres: 0.17 mm across read in mm, not small enough for the micrometre warning
    m = write_stl(tmp_path / "pin_in_metres.stl", box((0.1, 0.1, 0.1), at=(0.1, 0, 0)))
    with pytest.warns(MeshcheckWarning, match="mixed units") as caught:
        load_bodies([mm, m])
    (message,) = [str(w.message) for w in caught]
    assert message.startswith(f"{mm}: is 4000 times the size of {m}")


def _3mf_mesh(mesh) -> str:
    verts = "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in mesh.vertices)
    tris = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in mesh.faces)
    return f"<mesh><vertices>{verts}</vertices><triangles>{tris}</triangles></mesh>"


# ------------------------------------------------------------------------------------------
# Several shells in one file


def test_overlapping_closed_shells_warn_and_suggest_split(tmp_path):
    import meshcheck

    path = write_stl(tmp_path / "assy.stl", trimesh.util.concatenate([box(), box(at=(0.5, 0, 0))]))
    (body,) = load_bodies([path])  # the loader keeps it; the check warns (verify.shells)
    assert len(body.mesh.faces) == 24
    with (
        pytest.warns(MeshcheckWarning, match="the only part: nothing to compare"),
        pytest.warns(MeshcheckWarning, match=r"assy\.stl: closed shells 1 and 2 .* --split"),
    ):
        result = meshcheck.check([path], cache_dir=None)
    assert result.warnings[-2].startswith(f"{path}: closed shells 1 and 2 of this part overlap")
    assert result.warnings[-1].endswith("it holds 2 shells: --split checks them against each other")
    split = meshcheck.check([path], split=True, cache_dir=None)  # no warning: the clash is checked
    assert [str(f.status) for f in split.findings] == ["interference"]


def test_touching_or_apart_shells_do_not_warn(tmp_path):
    # 1e-6 apart: touching within the 1e-6 relative tolerance (exactly shared corners would be
    # merged into one vertex, making the file one non-manifold shell)
    touching = trimesh.util.concatenate([box(), box(at=(1 + 1e-6, 0, 0)), box(at=(5, 0, 0))])
    path = write_stl(tmp_path / "assy.stl", touching)
    (body,) = load_bodies([path])
    assert len(body.mesh.faces) == 36
    warn_overlapping_shells([body])  # filterwarnings = error: any warning fails


def test_shells_of_a_tessellated_solid_crossing_within_both_deflections_do_not_overlap():
    # Two solids of one STEP part that touch, each meshed within 0.005 of its faces, can show
    # chords crossing by up to both deflections: that is contact, not a shared volume. The same
    # crossing in a mesh file (no deflection) and a deeper one are overlaps.
    from meshcheck.verify.shells import overlapping_shells

    crossing = trimesh.util.concatenate([box(), box(at=(1 - 0.008, 0, 0))])
    assert overlapping_shells(crossing, deflection=0.005) is None
    assert overlapping_shells(crossing) == (1, 2)
    deeper = trimesh.util.concatenate([box(), box(at=(1 - 0.012, 0, 0))])
    assert overlapping_shells(deeper, deflection=0.005) == (1, 2)


def test_mm_stl_beside_a_metre_gltf_is_checked_in_one_unit(tmp_path):
    import meshcheck

    # 0.1 read the 1 m cube 2 m away as a 1 mm cube 2 mm away: buried in the frame, a clash
    stl = write_stl(tmp_path / "frame.stl", box((1000, 1000, 1000)))
    gltf = write_gltf(tmp_path / "pin.gltf", [("pin", (2, 0, 0))])
    result = meshcheck.check([stl, gltf], cache_dir=None)
    assert result.findings == []
    touching = write_gltf(tmp_path / "near.gltf", [("pin", (1.0, 0, 0))])
    (finding,) = meshcheck.check([stl, touching], cache_dir=None).findings
    assert finding.status == "touching"
