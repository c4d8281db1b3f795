"""STEP tessellation: a part of several solids is several closed shells, and a face BRepMesh
left without triangles is meshed again with its seams closed and its deflection measured.

The solids are built by OpenCASCADE here (tests/step_writer.py); the known answers are the CAD
volumes in closed form and the requested deflection.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from step_writer import box, cut, cylinder, write_step

from meshcheck.execute import Task
from meshcheck.load import load_bodies
from meshcheck.load.step import read_step
from meshcheck.load.step.tessellate import (
    DEFAULT_ANGULAR_DEFLECTION,
    _meshed_products,
    face_arrays,
    face_deviation,
    follows_edges,
    mend_faces,
    product_mesh,
    products,
    triangulate,
    triangulated,
    welded_triangles,
)
from meshcheck.mesh import is_closed, merge_vertices, split_shells

EYE = np.eye(4)


def shared_face_pair():
    """Two 2 x 2 x 1 boxes stacked in z, one compound whose solids share the face z = 1
    (OpenCASCADE's general fuse keeps both solids and makes their common face one face)."""
    from OCP.BOPAlgo import BOPAlgo_Builder

    builder = BOPAlgo_Builder()
    builder.AddArgument(box((0, 0, 0), (2, 2, 1)))
    builder.AddArgument(box((0, 0, 1), (2, 2, 2)))
    builder.Perform()
    return builder.Shape()


def chamfered_plate():
    """A 10 x 10 x 3 plate with a 1.7 radius hole whose entry has a 0.3 x 45 degree chamfer:
    volume 300 - pi 1.7^2 3 - the chamfer ring."""
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCone
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    plate = cut(box((-5, -5, -3), (5, 5, 0)), cylinder(1.7, -4, 1))
    cone = BRepPrimAPI_MakeCone(gp_Ax2(gp_Pnt(0, 0, -0.3), gp_Dir(0, 0, 1)), 1.7, 2.3, 0.6)
    return cut(plate, cone.Shape())


def chamfered_plate_volume() -> float:
    """CAD volume of ``chamfered_plate``: the chamfer is a frustum from r 1.7 to 2.0 over 0.3,
    less the hole's cylinder over the same height."""
    frustum = np.pi * 0.3 / 3 * (1.7**2 + 1.7 * 2.0 + 2.0**2)
    return 300 - np.pi * 1.7**2 * 3 - (frustum - np.pi * 1.7**2 * 0.3)


def faces_of(shape) -> list:
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out, explorer = [], TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        out.append(TopoDS.Face(explorer.Current()))
        explorer.Next()
    return out


def is_cone(face) -> bool:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone

    return BRepAdaptor_Surface(face).GetType() == GeomAbs_Cone


# --------------------------------------------------------------------------------------------
# Several solids in one part


def test_a_part_of_two_solids_sharing_a_face_is_two_closed_shells(tmp_path):
    path = write_step(tmp_path / "pair.step", {"pair": shared_face_pair()}, [("pair", EYE)])
    ((name, mesh, _),) = read_step(path).items
    shells = split_shells(mesh)
    assert name == "pair" and len(shells) == 2
    assert all(is_closed(shell) for shell in shells)
    assert sorted(float(s.volume) for s in shells) == pytest.approx([4.0, 4.0])


def test_loading_a_part_of_two_solids_sharing_a_face_keeps_it_closed(tmp_path):
    path = write_step(tmp_path / "pair.step", {"pair": shared_face_pair()}, [("pair", EYE)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # "mesh is not closed" would be raised here
        (body,) = load_bodies([path])
    assert is_closed(body.mesh) and float(body.mesh.volume) == pytest.approx(8.0)
    assert len(split_shells(body.mesh)) == 2


def test_vertices_of_different_shells_are_not_merged():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.0, 0, 0], [1, 0, 0], [0, 0, 1]])
    f = np.array([[0, 1, 2], [3, 4, 5]])
    assert len(merge_vertices(v, f)[0]) == 4
    merged, faces = merge_vertices(v, f, shells=np.array([0, 0, 0, 1, 1, 1]))
    assert len(merged) == 6 and faces.tolist() == f.tolist()


# --------------------------------------------------------------------------------------------
# Faces meshed again


def meshed_chamfered_plate(deflection: float):
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    plate = chamfered_plate()
    BRepMesh_IncrementalMesh(plate, deflection, False, 0.5, False)
    return plate


def test_a_face_left_without_triangles_is_meshed_again_with_its_seams_closed():
    from OCP.BRep import BRep_Builder

    deflection = 0.005
    plate = meshed_chamfered_plate(deflection)
    (chamfer,) = [face for face in faces_of(plate) if is_cone(face)]
    assert all(follows_edges(face) for face in faces_of(plate))
    BRep_Builder().UpdateFace(chamfer, None)  # what BRepMesh leaves when a face fails
    assert not follows_edges(chamfer)

    mesh, deviation = product_mesh(plate, "plate", 1.0, deflection, angular=0.5)
    assert follows_edges(chamfer)
    assert is_closed(mesh)
    # meshed coarser inside than on its edges: its measured distance is what is reported
    assert deviation == face_deviation(chamfer) and 0 < deviation <= 2 * deflection
    # the chords lie within the deflection of the faces: the volume within their area times it
    area = 2 * (100 - np.pi * 1.7**2) + 40 * 3 + 2 * np.pi * 1.7 * 3 + 2 * np.pi * 2.0 * 0.43
    assert float(mesh.volume) == pytest.approx(chamfered_plate_volume(), abs=area * deviation)


def test_triangles_weld_into_the_mesh_product_mesh_makes_unless_a_face_must_be_mended():
    """A product triangulated apart (``triangulate``: the worker that reads a file ahead) and
    welded here is the mesh ``product_mesh`` makes; with a face left without triangles it
    welds open, and ``welded_triangles`` leaves it to ``mesh_task``, which mends it."""
    from OCP.BRep import BRep_Builder

    deflection = 0.005
    plate = meshed_chamfered_plate(deflection)
    welded = welded_triangles([(True, face_arrays(plate))], "plate", 1.0, deflection)
    made, deviation = product_mesh(plate, "plate", 1.0, deflection, angular=0.5)
    assert deviation == 0.0 and is_closed(welded)
    assert np.array_equal(welded.vertices, made.vertices)
    assert np.array_equal(welded.faces, made.faces)
    (chamfer,) = [face for face in faces_of(plate) if is_cone(face)]
    BRep_Builder().UpdateFace(chamfer, None)
    assert welded_triangles([(True, face_arrays(plate))], "plate", 1.0, deflection) is None


def test_products_meshed_from_their_triangles_are_the_products_meshed_here(tmp_path):
    """``_meshed_products`` with every product's triangles (one of them welding open, so meshed
    by ``mesh_task`` after all) gives the meshes it gives without them, array for array."""
    from meshcheck.load.step.document import read_document

    shapes = {"block": box((0, 0, 0), (4, 4, 4)), "pin": cylinder(1.0, 0.0, 9.0)}
    path = write_step(str(tmp_path / "two.step"), shapes, [("block", EYE), ("pin", EYE)])
    with open(path, "rb") as f:
        data = f.read()
    angular = DEFAULT_ANGULAR_DEFLECTION
    found = products(read_document(data, path), path, None, angular, "mm")
    alone = _meshed_products(found, path, angular, 1.0, None)
    deflection = found.deflection_mm
    found.triangles = {k: triangulate(t, 1.0, deflection, angular) for k, t in found.texts.items()}
    first = next(iter(found.triangles))
    is_solid, (vertices, faces, same) = found.triangles[first][0]
    found.triangles[first][0] = (is_solid, (vertices, faces[1:], same))  # a triangle missing
    assert welded_triangles(found.triangles[first], "x", 1.0, deflection) is None
    welded = _meshed_products(found, path, angular, 1.0, None)
    assert list(welded) == list(alone)
    for key, (mesh, deviation) in alone.items():
        assert np.array_equal(welded[key][0].vertices, mesh.vertices)
        assert np.array_equal(welded[key][0].faces, mesh.faces)
        assert welded[key][1] == deviation and welded[key][0].metadata == mesh.metadata


@pytest.mark.parametrize("name", ["tests/data/step/box_sides.STEP", "sample_meshes/assembly.step"])
def test_products_meshed_in_threads_are_the_products_meshed_in_one(name):
    """The worker that reads a file ahead meshes in threads (``in_parallel``): the coarse
    counts and every face's triangles are the ones one thread makes."""
    import os

    from meshcheck.load.step.document import read_document

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", name)
    with open(path, "rb") as f:
        data = f.read()
    angular = DEFAULT_ANGULAR_DEFLECTION
    made = []
    for threads in (1, 2):
        found = products(read_document(data, path), path, None, angular, "mm", threads=threads)
        made.append((found.costs, triangulated(found, "mm", angular, threads)))
    (costs, one), (costs_threads, threaded) = made
    assert costs == costs_threads and list(one) == list(threaded)
    for key, parts in one.items():
        assert len(parts) == len(threaded[key])
        for (is_solid, arrays), (is_solid_threads, arrays_threads) in zip(
            parts, threaded[key], strict=True
        ):
            assert is_solid == is_solid_threads
            for a, b in zip(arrays, arrays_threads, strict=True):
                assert np.array_equal(a, b)


def test_mend_faces_leaves_a_fully_meshed_solid_alone():
    plate = meshed_chamfered_plate(0.01)
    assert mend_faces(plate, 0.01, 0.5) is None


def test_face_deviation_is_the_chord_sag_of_a_cylinder():
    # A cylinder's facets meet it along their sides' ends: the farthest point of a facet from
    # it is the middle of a chord across n equal steps, r (1 - cos(pi / n)) inside.
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    pin = cylinder(2.0, 0, 1)
    BRepMesh_IncrementalMesh(pin, 0.01, False, 0.5, False)
    (side,) = [face for face in faces_of(pin) if not _is_plane(face)]
    location = TopLoc_Location()
    tri = BRep_Tool.Triangulation_s(side, location)
    explorer = TopExp_Explorer(side, TopAbs_EDGE)
    steps = set()
    while explorer.More():
        edge = TopoDS.Edge(explorer.Current())
        explorer.Next()
        if not BRep_Tool.IsClosed_s(edge, side):  # the two circles, not the seam
            steps.add(BRep_Tool.PolygonOnTriangulation_s(edge, tri, location).NbNodes() - 1)
    (n,) = steps
    assert face_deviation(side) == pytest.approx(2.0 * (1 - np.cos(np.pi / n)), rel=1e-6)
    assert face_deviation(side) <= 0.01


def _is_plane(face) -> bool:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Plane

    return BRepAdaptor_Surface(face).GetType() == GeomAbs_Plane


# --------------------------------------------------------------------------------------------
# Each product's deflection


def test_a_product_meshed_again_coarser_holds_its_own_deflection(tmp_path, monkeypatch):
    # A face meshed again may lie farther from its triangles than the deflection asked: that
    # product's parts hold the measured distance, the others the deflection asked, also when
    # the tessellation comes back from the cache.
    from meshcheck.cache import TessellationCache
    from meshcheck.load.step import tessellate

    path = write_step(
        tmp_path / "two.step",
        {"plate": box((0, 0, 0), (10, 10, 2)), "pin": cylinder(1.0, 2, 6)},
        [("plate", EYE), ("pin", EYE)],
    )
    real = tessellate.product_mesh

    def product_mesh(shape, name, to_unit, deflection, *, angular):
        mesh, deviation = real(shape, name, to_unit, deflection, angular=angular)
        return mesh, (0.02 if name.endswith("#plate") else deviation)

    monkeypatch.setattr(tessellate, "product_mesh", product_mesh)
    cache = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    fresh = read_step(path, cache=cache)
    again = read_step(path, cache=cache)  # from the cache
    for assembly in (fresh, again):
        held = {n: m.metadata["deflection"] for n, m, _ in assembly.items}
        assert held == {"plate": 0.02, "pin": 0.005}
        assert assembly.deflection == 0.02  # the file's: the largest
    bodies = {b.name.rsplit("#", 1)[1]: b.deflection for b in load_bodies([path])}
    assert bodies == {"plate": 0.02, "pin": 0.005}


# --------------------------------------------------------------------------------------------
# Products meshed in workers


def four_products(path) -> str:
    """A plate with two holes, a pin in one and a chamfered plate beside it, a block on top:
    four products, more than a two-job pool has processes."""
    plate = cut(box((-30, -10, 0), (30, 10, 6)), cylinder(2.5, -1, 7, -20, 0), cylinder(2, -1, 7))
    products = {
        "plate": plate,
        "pin": cylinder(2.5, -6.0, 12.0, -20, 0),
        "chamfered": chamfered_plate(),
        "block": box((10, -5, 6), (20, 5, 9)),
    }
    instances = [(name, EYE) for name in products]
    return write_step(path, products, instances)


def test_products_meshed_in_prepared_workers_are_the_ones_meshed_here(tmp_path, monkeypatch):
    from meshcheck.execute import LocalPool
    from meshcheck.load.step import read, tessellate

    monkeypatch.setattr(read, "PREPARE_BYTES", 0)  # these files count as large ones

    path = four_products(tmp_path / "four.step")
    other = write_step(  # a second file: its product labels are the first one's
        tmp_path / "other.step",
        {
            "plate": box((0, 0, 0), (9, 9, 1)),
            "pin": cylinder(1.0, 1, 4),
            "cap": box((0, 0, 4), (2, 2, 5)),
        },
        [("plate", EYE), ("pin", EYE), ("cap", EYE)],
    )
    here, other_here = read_step(path), read_step(other)
    with LocalPool(2) as pool:
        pool.prepare(tessellate.PREPARE)  # what a run with a large STEP file does
        assert tessellate._meshes_in_workers(pool, 4)
        mapped, real_map = [], pool.map

        def map_and_note(function, tasks, **kwargs):
            mapped.append((function, len(tasks)))
            return real_map(function, tasks, **kwargs)

        pool.map = map_and_note
        there = read_step(path, executor=pool)
        other_there = read_step(other, executor=pool)  # the same workers, what they were sent
        pool.map = real_map
        assert mapped == [("meshcheck.load.step.tessellate:mesh_task", n) for n in (4, 3)]
        ran_in = pool.map("meshcheck.execute:is_imported", [Task(("OCP.OCP",))])
    assert ran_in == [True]  # the worker loaded OpenCASCADE before its first task
    for one, two in ((here, there), (other_here, other_there)):
        assert [n for n, _, _ in one.items] == [n for n, _, _ in two.items]
        for (_, a, pa), (_, b, pb) in zip(one.items, two.items, strict=True):
            assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
            assert np.array_equal(pa, pb) and a.metadata == b.metadata
        assert one.deflection == two.deflection


def test_a_pool_without_opencascade_loaded_meshes_nothing_in_its_workers():
    from meshcheck.execute import Executor, LocalPool
    from meshcheck.load.step import tessellate

    with LocalPool(2) as pool:  # not prepared: a small file's run
        assert not tessellate._meshes_in_workers(pool, 4)
    assert not tessellate._meshes_in_workers(Executor(), 4)
    assert not tessellate._meshes_in_workers(None, 4)


def test_a_product_that_cannot_be_meshed_is_an_input_error_naming_it(tmp_path, monkeypatch):
    from meshcheck.errors import InputError
    from meshcheck.load.step import tessellate

    path = four_products(tmp_path / "four.step")

    def product_mesh(shape, name, to_unit, deflection, *, angular):
        raise InputError(name, "vertices have NaN or infinite coordinates")

    monkeypatch.setattr(tessellate, "product_mesh", product_mesh)
    with pytest.raises(InputError) as caught:
        read_step(path)
    assert caught.value.path == f"{path}#block"  # the first product in name order
