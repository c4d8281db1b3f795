"""STEP input: names, instances, units, closed solids, tessellation error, cache, broken files.

Every STEP file here is written at test time by OpenCASCADE (cadquery-ocp, tests/step_writer.py)
with known answers: a clearance or a depth set in the CAD model, exact volumes in closed form
(never from the OpenCASCADE calls meshcheck's B-rep stage makes), placements chosen by the test.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from step_writer import (
    annulus_volume,
    box,
    cut,
    cylinder,
    fillet,
    fuse,
    placement,
    rounded_box_volume,
    write_step,
)

from meshcheck.cache import TessellationCache, tessellation_key
from meshcheck.cli import main
from meshcheck.errors import InputError, MeshcheckWarning
from meshcheck.load import Body, load_bodies, mesh_digest
from meshcheck.load.step import DEFAULT_DEFLECTION_MM, close_mesh, read_step, step_unit
from meshcheck.pipeline import check, check_bodies

EYE = np.eye(4)


def is_closed(mesh: trimesh.Trimesh) -> bool:
    """Every edge used by exactly two triangles, once in each direction (consistent winding)."""
    f = np.asarray(mesh.faces)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    undirected = np.sort(directed, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    return bool(np.all(counts == 2) and np.all(directed_counts == 1))


def side_chord_radii(pin: trimesh.Trimesh) -> np.ndarray:
    """Distance from the z axis of the edge midpoints of a z-cylinder's side facets.

    A chord's midpoint is the deepest point of a facet below the cylinder it approximates.
    """
    tri = pin.triangles
    tri = tri[np.ptp(tri[..., 2], axis=1) > 1e-6]  # the cap triangles lie in one plane
    return np.linalg.norm(((tri + np.roll(tri, -1, axis=1)) / 2)[..., :2], axis=-1)


def pin_in_housing(
    path, *, hole: float, pin: float, unit: str = "MM", half: float = 10.0, height: float = 10.0
) -> str:
    """A housing ``height`` thick with a hole of radius ``hole``, a pin of radius ``pin`` in it."""
    half = max(half, 1.4 * hole)
    housing = cut(box((-half, -half, 0), (half, half, height)), cylinder(hole, -1, height + 1))
    return write_step(
        path,
        {"housing": housing, "pin": cylinder(pin, -0.2 * height, 1.2 * height)},
        [("housing", EYE), ("pin", placement(angle_deg=7.0))],  # facets out of phase
        unit=unit,
    )


def bodies_of(path, **kwargs) -> list[Body]:
    """The parts of a STEP file, as ``load_bodies`` makes them (in the file's unit)."""
    asm = read_step(str(path), **kwargs)
    return [
        Body(
            f"{path}#{n}",
            str(path),
            m,
            t,
            units=asm.unit,
            deflection=asm.deflection,
            brep=asm.solids,
        )
        for n, m, t in asm.items
    ]


def only_finding(bodies):
    findings = check_bodies(bodies, clearance=0.5, jobs=1).findings
    assert len(findings) == 1, findings
    return findings[0]


@pytest.fixture(scope="session")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("step")
    bolt = fuse(cylinder(5.0, 10.0, 14.0), cylinder(3.0, -4.0, 10.0))
    plate = cut(
        box((-50, -30, 0), (50, 30, 10)), *[cylinder(3.3, -1, 11, x, 0) for x in (-30, 0, 30)]
    )
    out = {
        "clear": pin_in_housing(d / "clear.step", hole=3.1, pin=3.0),
        "over": pin_in_housing(d / "over.step", hole=3.1, pin=3.3),
        "resting": write_step(
            d / "resting.step",
            {"base": box((0, 0, 0), (10, 10, 5)), "block": box((2, 2, 0), (8, 8, 3))},
            [("base", EYE), ("block", placement((0, 0, 5)))],
        ),
        "bolts": write_step(
            d / "bolts.step",
            {"plate": plate, "bolt": bolt},
            [
                ("plate", EYE),
                ("bolt", placement((30, 0, 0), angle_deg=90)),
                ("bolt", placement((-30, 0, 0))),
                ("bolt", placement((0, 0, 0), angle_deg=45)),
            ],
        ),
        # 0.004 in (0.1016 mm) radial clearance in a 1 x 1 x 0.5 in housing
        "inch": pin_in_housing(
            d / "inch.step", hole=0.125, pin=0.121, unit="INCH", half=0.5, height=0.5
        ),
    }
    return {k: str(v) for k, v in out.items()}


# --------------------------------------------------------------------------------------------
# Tessellation error: the CAD model's clearance and depth, within the promised bounds


@pytest.mark.parametrize("hole", [3.1, pytest.param(25.0, marks=pytest.mark.slow)])
def test_pin_with_clearance_measures_its_cad_clearance(tmp_path, hole):
    path = pin_in_housing(tmp_path / "pin.STEP", hole=hole, pin=hole - 0.1)
    finding = only_finding(bodies_of(path))
    assert finding.status == "clearance"
    assert finding.distance == pytest.approx(0.1, abs=0.01)


@pytest.mark.parametrize("hole", [3.1, pytest.param(25.0, marks=pytest.mark.slow)])
def test_oversized_pin_measures_its_cad_depth(tmp_path, hole):
    path = pin_in_housing(tmp_path / "pin.stp", hole=hole, pin=hole + 0.2)
    finding = only_finding(bodies_of(path))
    assert finding.status == "interference"
    assert finding.depth == pytest.approx(0.2, abs=0.03)


def test_facets_lie_within_the_deflection_of_the_cad_faces(files):
    asm = read_step(files["clear"])
    assert asm.deflection == pytest.approx(DEFAULT_DEFLECTION_MM)
    pin = dict((n, m) for n, m, _ in asm.items)["pin"]
    tri = pin.triangles[np.ptp(pin.triangles[..., 2], axis=1) > 1e-6]  # side triangles
    radii = np.linalg.norm(tri[..., :2], axis=-1)
    assert np.all(np.abs(radii - 3.0) < 1e-5)  # vertices on the cylinder (float32 precision)
    mid = side_chord_radii(pin)
    assert mid.min() >= 3.0 - asm.deflection
    assert mid.min() < 3.0 - asm.deflection / 10  # and the deflection is what it says


def test_a_coarser_deflection_gives_fewer_triangles_and_says_so(files):
    fine = read_step(files["clear"])
    coarse = read_step(files["clear"], deflection=0.05)
    assert coarse.deflection == 0.05
    assert sum(len(m.faces) for _, m, _ in coarse.items) < sum(
        len(m.faces) for _, m, _ in fine.items
    )
    with pytest.raises(ValueError):
        read_step(files["clear"], deflection=-1.0)


# --------------------------------------------------------------------------------------------
# Closed solids


def test_closed_solids_stay_closed_with_their_cad_volume(tmp_path):
    block = fillet(box((-10, -10, 0), (10, 10, 10)), 1.5)
    # a hole through the flat middle, a blind one 5 deep in the top's flat part
    block = cut(block, cylinder(3.1, -1, 11, 2, 1), cylinder(1.0, 5, 12, -6, -6))
    cad = rounded_box_volume((20, 20, 10), 1.5) - np.pi * (3.1**2 * 10 + 1.0**2 * 5)
    path = write_step(tmp_path / "block.step", {"block": block}, [("block", EYE)])
    ((name, mesh, _),) = read_step(path).items
    assert name == "block"
    assert is_closed(mesh)
    # chords cut inside curved faces: a little less volume than the CAD solid, never more
    assert cad * 0.998 < mesh.volume < cad


def test_every_solid_of_every_file_is_closed(files):
    for path in files.values():
        for name, mesh, _ in read_step(path).items:
            assert is_closed(mesh), (path, name)
            assert mesh.volume > 0, (path, name)


def test_close_mesh_welds_faces_that_were_tessellated_apart():
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    split = cube.vertices[cube.faces].reshape(-1, 3)
    split = split + np.random.default_rng(0).uniform(-1e-9, 1e-9, split.shape)
    faces = np.arange(len(split)).reshape(-1, 3)
    assert not trimesh.Trimesh(split, faces, process=False).is_watertight
    mesh = close_mesh(split, faces, deflection=1e-3)
    assert is_closed(mesh) and mesh.volume == pytest.approx(8.0)
    inverted = close_mesh(split, faces[:, ::-1], deflection=1e-3)
    assert inverted.volume == pytest.approx(8.0)  # faced outward again


def test_close_mesh_joins_the_copies_of_a_shared_edge_whatever_their_distance():
    # Each face evaluates an edge's nodes on its own surface: a sloppy export puts the copies up
    # to the edge's tolerance apart, beyond any distance weld that keeps small features. The
    # topology says which copies are one node.
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    split = cube.vertices[cube.faces].reshape(-1, 3)
    faces = np.arange(len(split)).reshape(-1, 3)
    moved = split.copy()
    moved[faces[:2].ravel()] += 1e-4  # one side's copies 1.7e-4 off, the weld is 1e-5
    same = np.array(
        [(i, j) for i in range(len(split)) for j in range(i) if np.allclose(split[i], split[j])]
    )
    assert not is_closed(close_mesh(moved, faces, deflection=1e-3))
    mesh = close_mesh(moved, faces, deflection=1e-3, same=same)
    assert is_closed(mesh) and len(mesh.vertices) == 8


def test_face_arrays_name_the_copies_of_every_edge_two_faces_share():
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    from meshcheck.load.step.tessellate import face_arrays

    shape = cut(box((0, 0, 0), (4, 4, 4)), cylinder(1.0, -1, 5, 2, 2))
    BRepMesh_IncrementalMesh(shape, 0.01, False, 0.5, False)
    vertices, faces, same = face_arrays(shape)
    assert len(same)
    assert np.abs(vertices[same[:, 0]] - vertices[same[:, 1]]).max() < 1e-9
    assert is_closed(close_mesh(vertices, faces, 1e-9, same=same))  # no distance weld needed


# --------------------------------------------------------------------------------------------
# Names, instances, placements


def test_repeated_instances_get_stable_names_and_their_placements(files):
    asm = read_step(files["bolts"])
    names = [n for n, _, _ in asm.items]
    assert names == ["bolt", "bolt_1", "bolt_2", "plate"]
    meshes = {id(m) for n, m, _ in asm.items if n.startswith("bolt")}
    assert len(meshes) == 1  # one product, one mesh, three placements
    placed = {n: t for n, _, t in asm.items}
    xs = sorted(round(t[0, 3], 6) for n, t in placed.items() if n != "plate")
    assert xs == [-30.0, 0.0, 30.0]
    for n, mesh, t in asm.items:
        if n == "plate":
            continue
        world = mesh.copy().apply_transform(t)
        centre = world.bounds.mean(axis=0)[:2]
        assert np.allclose(centre, t[:2, 3], atol=1e-5)  # bolt axis through its placement
        assert np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6)


def test_names_and_triangles_do_not_depend_on_the_hash_seed(files):
    # same names, placements and triangles (finding IDs hash the meshes) in every process
    code = (
        "import sys\n"
        "from meshcheck.load import mesh_digest\n"
        "from meshcheck.load.step import read_step\n"
        "items = read_step(sys.argv[1]).items\n"
        "print([(n, t[:3, 3].round(6).tolist(), mesh_digest(m)) for n, m, t in items])\n"
    )
    outputs = {
        subprocess.run(
            [sys.executable, "-c", code, files["bolts"]],
            env={**os.environ, "PYTHONHASHSEED": seed},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for seed in ("1", "2")
    }
    here = [
        (n, t[:3, 3].round(6).tolist(), mesh_digest(m))
        for n, m, t in read_step(files["bolts"]).items
    ]
    assert outputs == {f"{here}\n"}


def test_bolts_in_plate_through_the_loader(files):
    bodies = load_bodies([files["bolts"]])
    path = files["bolts"]
    assert [b.name for b in bodies] == [
        f"{path}#bolt",
        f"{path}#bolt_1",
        f"{path}#bolt_2",
        f"{path}#plate",
    ]
    result = check_bodies(bodies, clearance=0.5, jobs=1)
    statuses = {(f.a, f.b): f.status for f in result.findings}
    # heads rest on the plate (touching); 0.3 mm radial clearance in the holes is beyond reach
    assert set(statuses.values()) == {"touching"}
    assert len(statuses) == 3


def test_finding_ids_follow_the_solids_not_their_triangles(files, tmp_path):
    # A STEP part's ID hashes its product's B-rep and its placement: another deflection (or
    # mesher) changes every triangle but no part, so baselines and approvals by ID still hold.
    bolt = fuse(cylinder(5.0, 10.0, 14.0), cylinder(3.0, -4.0, 10.0))
    doubled = write_step(tmp_path / "doubled.step", {"bolt": bolt}, [("bolt", EYE), ("bolt", EYE)])

    def ids(path, *options):
        args = [path, "--no-cache", "--format", "json", "-j", "1", *options]
        result = CliRunner().invoke(main, args)
        assert result.exit_code in (0, 1), result.output  # touching passes, a duplicate fails
        results = json.loads(result.stdout)["results"]
        return {(r["a"], r["b"], r["status"]): r["id"] for r in results}

    for path, found in ((files["bolts"], 3), (str(doubled), 1)):
        fine, coarse = ids(path), ids(path, "--step-deflection", "0.05")
        assert len(fine) == found and fine == coarse
        assert len(set(fine.values())) == found  # instances placed apart keep apart
        meshes = [
            {mesh_digest(m) for _, m, _ in read_step(path, deflection=d).items}
            for d in (None, 0.05)
        ]
        assert not meshes[0] & meshes[1]  # not one triangle mesh in common


def test_pattern_groups_follow_the_solids_not_their_triangles(tmp_path):
    # Three plates, each pierced by its pin the same way (one turned a quarter): one pattern
    # group, whose ID hashes the products' B-rep and frames, so another deflection keeps it.
    plate, pin = box((-5, -5, 0), (5, 5, 2)), cylinder(1.0, -1.0, 3.0, x=1.5)
    places = [placement((0, 0, 0)), placement((30, 0, 0)), placement((0, 30, 0), angle_deg=90)]
    path = str(
        write_step(
            tmp_path / "pierced.step",
            {"plate": plate, "pin": pin},
            [("plate", p) for p in places] + [("pin", p) for p in places],
        )
    )

    def groups(*options):
        args = [path, "--no-cache", "--format", "json", "-j", "1", *options]
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 1, result.output
        report = json.loads(result.stdout)
        return [(g["id"], g["kind"], sorted(g["findings"])) for g in report["groups"]]

    fine, coarse = groups(), groups("--step-deflection", "0.05")
    assert fine == coarse
    assert [(kind, len(ids)) for _, kind, ids in fine] == [("pattern", 3)]


def test_faces_resting_on_faces_touch(files):
    finding = only_finding(bodies_of(files["resting"]))
    assert finding.status == "touching"
    assert finding.distance == pytest.approx(0.0, abs=1e-5)


# --------------------------------------------------------------------------------------------
# Units


def test_inch_file_reads_in_inches(files):
    asm = read_step(files["inch"])
    assert asm.unit == "in"
    housing = dict((n, m) for n, m, _ in asm.items)["housing"]
    assert np.allclose(housing.bounds, [[-0.5, -0.5, 0], [0.5, 0.5, 0.5]], atol=1e-6)
    assert asm.deflection == pytest.approx(DEFAULT_DEFLECTION_MM / 25.4)
    # the deflection holds in inches, and is used (not 25.4 times finer)
    pin = dict((n, m) for n, m, _ in asm.items)["pin"]
    assert 0.121 - asm.deflection <= side_chord_radii(pin).min() < 0.121 - asm.deflection / 10
    finding = only_finding(bodies_of(files["inch"]))
    assert finding.distance == pytest.approx(0.004, abs=0.01 / 25.4)


def test_deflection_in_another_unit_is_converted(files):
    asm = read_step(files["inch"], deflection=0.0254, deflection_unit="mm")
    assert asm.deflection == pytest.approx(0.001)


def test_millimetre_file_reads_in_millimetres(files):
    asm = read_step(files["clear"])
    assert asm.unit == "mm"
    housing = dict((n, m) for n, m, _ in asm.items)["housing"]
    assert np.allclose(housing.bounds, [[-10, -10, 0], [10, 10, 10]], atol=1e-5)


@pytest.mark.parametrize(
    "unit, expected",
    [
        ("SI_UNIT(.MILLI.,.METRE.)", "mm"),
        ("SI_UNIT($,.METRE.)", "m"),
        ("SI_UNIT(.CENTI.,.METRE.)", "cm"),
        ("CONVERSION_BASED_UNIT('INCH',#9)", "in"),
        ("CONVERSION_BASED_UNIT('FOOT',#9)", "ft"),
    ],
)
def test_step_unit_reads_the_declared_length_unit(unit, expected):
    data = (
        "#9=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.));\n"
        f"#5=( LENGTH_UNIT() NAMED_UNIT(*) {unit} );\n"
        "#6=(GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNIT_ASSIGNED_CONTEXT((#5,#7)) "
        "REPRESENTATION_CONTEXT('a;b',''));\n"
    )
    assert step_unit(data.encode()) == expected


def test_step_unit_without_a_declared_unit_warns_and_reads_millimetres():
    with pytest.warns(MeshcheckWarning, match="x.step: declares no length unit"):
        assert step_unit(b"#1=PRODUCT('a','a','',(#2));", "x.step") == "mm"


# --------------------------------------------------------------------------------------------
# Broken files, the command line


@pytest.mark.parametrize(
    "content",
    [
        b"ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1 = GARBAGE(;\nENDSEC;\nEND-ISO-10303-21;\n",
        b"solid nothing\nendsolid\n",
        b"\x00\x01\x02" * 100,
    ],
)
def test_broken_step_is_one_line_exit_3(tmp_path, content, capfd):
    path = tmp_path / "broken.step"
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_step(str(path))
    assert info.value.path == str(path)
    assert "\n" not in str(info.value) and "cannot be read as STEP" in str(info.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # OpenCASCADE's own messages are kept off the streams
    result = CliRunner().invoke(main, [str(path)])
    assert result.exit_code == 3
    assert result.output.startswith(f"error: {path}: cannot be read as STEP")
    assert "Traceback" not in result.output


def test_truncated_step_is_an_input_error(files, tmp_path):
    path = tmp_path / "cut.step"
    path.write_bytes(open(files["bolts"], "rb").read()[:4000])
    with pytest.raises(InputError, match="cannot be read as STEP"):
        read_step(str(path))


def test_cli_reads_step_with_any_case_extension(files, tmp_path):
    path = tmp_path / "OVER.STP"
    path.write_bytes(open(files["over"], "rb").read())
    result = CliRunner().invoke(main, [str(path), "--jobs", "1", "--format", "json"])
    assert result.exit_code == 1, result.output
    doc = json.loads(result.stdout)
    assert [p["name"] for p in doc["parts"]] == [f"{path}#housing", f"{path}#pin"]
    assert [f["status"] for f in doc["results"]] == ["interference"]


# --------------------------------------------------------------------------------------------
# Cache


def test_cache_returns_the_same_assembly_and_misses_on_garbage(files, tmp_path):
    cache = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    first = read_step(files["bolts"], cache=cache)
    data = open(files["bolts"], "rb").read()
    key = tessellation_key(data, None, 0.5)
    assert os.path.exists(cache.path(key))
    again = read_step(files["bolts"], cache=cache)
    assert [n for n, _, _ in again.items] == [n for n, _, _ in first.items]
    for (_, m1, t1), (_, m2, t2) in zip(first.items, again.items, strict=True):
        assert np.array_equal(m1.vertices, m2.vertices) and np.array_equal(m1.faces, m2.faces)
        assert np.array_equal(t1, t2)
    assert len({id(m) for n, m, _ in again.items if n.startswith("bolt")}) == 1
    assert (again.unit, again.deflection) == (first.unit, first.deflection)
    # another deflection is another entry
    assert tessellation_key(data, 0.01, 0.5) != key
    # a garbled entry is a miss, and is rewritten
    with open(cache.path(key), "r+b") as f:
        f.seek(200)
        f.write(b"garbage" * 10)
    assert cache.get(key) is None
    read_step(files["bolts"], cache=cache)
    assert cache.get(key) is not None


def test_a_tessellation_entry_signed_with_another_key_is_a_miss(files, tmp_path):
    # The tessellation is the part's geometry: an entry anyone could write (a plain checksum)
    # could move a part out of a clash. Entries are signed with the cache's secret.
    forger = TessellationCache(str(tmp_path / "cache"), secret=b"f" * 32)
    ours = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    read_step(files["bolts"], cache=forger)
    key = tessellation_key(open(files["bolts"], "rb").read(), None, 0.5)
    assert forger.get(key) is not None
    assert ours.get(key) is None


# --------------------------------------------------------------------------------------------
# Line-to-line fits are touching, press fits interference: decided on the B-rep (verify/brep.py)
#
# The oracle is the common volume in closed form (step_writer.annulus_volume): 0 for a coincident
# fit, the press fit's annulus otherwise, whose thickness is the radial interference. Without the
# B-rep confirmation the coincident fits below are interference (the chords overlap) or pass a
# press fit thinner than the tessellation's tolerance as touching.


def fit(path, *, hole: float, pin: float, deflection=None, angle: float = 7.0):
    """A pin of radius ``pin`` through a hole of radius ``hole`` in a housing 4 thick (short, to
    keep meshes small): the finding, and the common volume of the two solids in closed form."""
    half = 1.4 * hole + 1.0
    housing = cut(box((-half, -half, 0), (half, half, 4)), cylinder(hole, -1, 5))
    pin_solid = cylinder(pin, -1, 5)
    path = write_step(
        path,
        {"housing": housing, "pin": pin_solid},
        [("housing", EYE), ("pin", placement(angle_deg=angle))],  # facets out of phase
    )
    bodies = bodies_of(path, deflection=deflection)
    findings = check_bodies(bodies, jobs=1).findings
    return findings, annulus_volume(hole, pin, 4.0)


@pytest.mark.parametrize(
    "radius, deflection",
    [(1.5, None), (3.0, None), (3.0, 0.02), (6.0, 0.002), (12.5, 0.05)],
)
def test_coincident_pin_in_hole_is_touching(tmp_path, radius, deflection):
    (finding,), oracle = fit(tmp_path / "fit.step", hole=radius, pin=radius, deflection=deflection)
    assert oracle == 0.0  # the solids share a surface, no volume
    assert finding.status == "touching", finding
    assert finding.depth is None and finding.volume is None
    # decided by the exact solids: the pair's own tolerance, not the tessellation's
    assert finding.tolerance < 1e-3


def test_coincident_bolts_in_plate_are_touching(tmp_path):
    # bolt shanks line to line with their holes (radius 2.5 both), heads resting on the plate
    plate = cut(box((-20, -10, 0), (20, 10, 6)), *[cylinder(2.5, -1, 7, x, 0) for x in (-10, 10)])
    bolt = fuse(cylinder(4.0, 6.0, 9.0), cylinder(2.5, -3.0, 6.0))
    path = write_step(
        tmp_path / "bolts.step",
        {"plate": plate, "bolt": bolt},
        [("plate", EYE), ("bolt", placement((-10, 0, 0))), ("bolt", placement((10, 0, 0), 30))],
    )
    findings = check_bodies(bodies_of(path), jobs=1).findings
    assert [f.status for f in findings] == ["touching", "touching"]


@pytest.mark.parametrize("interference", [0.01, 0.02, 0.05])  # on the diameter, mm
def test_press_fit_is_interference_with_its_cad_depth_and_volume(tmp_path, interference):
    (finding,), oracle = fit(tmp_path / "press.step", hole=3.0, pin=3.0 + interference / 2)
    assert finding.status == "interference"
    assert finding.volume == pytest.approx(oracle, rel=1e-6)
    assert finding.depth == pytest.approx(interference / 2, rel=1e-3)  # the annulus, radially


def test_press_fit_thinner_than_a_coarse_tessellation_is_still_interference(tmp_path):
    # 0.02 mm deflection: the meshes' tolerance is 0.04 mm, ten times this fit's 0.004 mm
    (finding,), oracle = fit(tmp_path / "press.step", hole=3.0, pin=3.004, deflection=0.02)
    assert oracle > 0
    assert finding.status == "interference" and finding.depth == pytest.approx(0.004, rel=1e-3)


def test_sample_at_a_coarse_deflection_still_reports_its_interference(tmp_path):
    # --step-deflection 1 makes the meshes' tolerance 2 mm: the 0.7 mm clash is decided on the
    # B-rep, never passed as touching
    result = CliRunner().invoke(
        main,
        ["sample_meshes/assembly.step", "--step-deflection", "1", "--no-cache", "--format", "json"],
    )
    assert result.exit_code == 1, result.output
    (clash,) = [r for r in json.loads(result.stdout)["results"] if r["status"] == "interference"]
    assert clash["b"].endswith("#plate") and clash["depth"] == pytest.approx(0.7, rel=1e-6)


def test_brep_verdicts_are_cached_and_a_warm_run_reports_the_same(tmp_path, monkeypatch):
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "test-secret")
    path = str(tmp_path / "press.step")
    fit(path, hole=3.0, pin=3.005)
    args = [path, "--cache-dir", str(tmp_path / "cache"), "--format", "json", "--jobs", "1"]
    cold = CliRunner().invoke(main, args)
    from meshcheck.load.step import read

    # a warm run reads no STEP document: neither to tessellate nor for the exact solids
    monkeypatch.setattr(read, "read_document", None)
    warm = CliRunner().invoke(main, args)
    assert cold.exit_code == warm.exit_code == 1, (cold.output, warm.output)
    assert cold.stdout == warm.stdout
    assert json.loads(cold.stdout)["results"][0]["depth"] == pytest.approx(0.005, rel=1e-3)


def test_no_stage_after_load_opens_the_step_file(tmp_path):
    # The exact solids travel with the bodies (Body.brep): once loaded, the file can be gone,
    # whether load tessellated it or took its tessellation from the cache.
    path = str(tmp_path / "press.step")
    (expected,), _ = fit(path, hole=3.0, pin=3.005)
    assert expected.tolerance < 1e-3  # decided on the B-rep
    cache = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    cold = load_bodies([path], cache=cache)
    warm = load_bodies([path], cache=cache)
    os.rename(path, path + ".gone")
    for bodies in (cold, warm):
        (finding,) = check_bodies(bodies, jobs=1).findings
        assert (finding.status, finding.depth, finding.volume, finding.tolerance) == (
            expected.status,
            expected.depth,
            expected.volume,
            expected.tolerance,
        )


def test_the_exact_solids_stay_in_the_process_that_read_them(files):
    # A body may be pickled (to a worker); its B-rep is not: the copy keeps only the identity.
    body = load_bodies([files["resting"]])[0]
    copy = pickle.loads(pickle.dumps(body))
    assert (copy.brep.path, copy.brep.digest) == (body.brep.path, body.brep.digest)
    with pytest.raises(InputError, match="stay in the process"):
        copy.brep.by_node()
    assert sorted(body.brep.by_node()) == ["base", "block"]


def brep_text(shape, folder) -> str:
    """A shape as OpenCASCADE writes it (BRepTools.Write): its topology, geometry, flags and
    any triangulation it holds."""
    from OCP.BRepTools import BRepTools

    path = str(folder / "shape.brep")
    BRepTools.Write_s(shape, path)
    return open(path).read()


def test_the_exact_solids_are_the_file_as_read_whatever_the_cache_held(
    files, tmp_path, monkeypatch
):
    # Tessellated here (the document load read is kept, not read again) or taken from the cache
    # (the bytes read into a document when asked): the same shapes, untouched by the mesher.
    from meshcheck.load.step import read

    cache = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    tessellated = read_step(files["bolts"], cache=cache).solids
    from_cache = read_step(files["bolts"], cache=cache).solids
    monkeypatch.setattr(read, "read_document", None)  # the tessellated file is not read again
    kept = tessellated.by_node()
    monkeypatch.undo()
    fresh = from_cache.by_node()
    assert sorted(kept) == sorted(fresh) == ["bolt", "bolt_1", "bolt_2", "plate"]
    for node in kept:
        text = brep_text(kept[node], tmp_path)
        assert text == brep_text(fresh[node], tmp_path)
        assert "Triangulations 0" in text


def test_a_run_reads_its_cache_key_once(files, tmp_path, monkeypatch):
    import meshcheck.cache as cache_package

    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "test-secret")
    calls = []
    read_key = cache_package.pair_secret
    monkeypatch.setattr(cache_package, "pair_secret", lambda: calls.append(1) or read_key())
    check([files["resting"], files["clear"]], cache_dir=str(tmp_path), jobs=1)
    assert len(calls) == 1


# --------------------------------------------------------------------------------------------
# Every solid read or refused: cycles, dangling and external references


def edited_sample(tmp_path, old: str, new: str) -> str:
    text = open("sample_meshes/assembly.step").read()
    assert old in text
    path = tmp_path / "edited.step"
    path.write_text(text.replace(old, new))
    return str(path)


NAUO = "#1795 = NEXT_ASSEMBLY_USAGE_OCCURRENCE('6','=>[0:1:1:5]','',#5,#1156,$);"


@pytest.mark.parametrize(
    "edit, message",
    [
        (NAUO.replace("#1156", "#5"), "assembly cycle: 'sample_assembly' -> 'sample_assembly'"),
        (NAUO.replace("#1156", "#99999"), "(NEXT_ASSEMBLY_USAGE_OCCURRENCE) refers to an entity"),
    ],
    ids=["cycle", "dangling"],
)
def test_cyclic_or_dangling_assembly_is_one_line_exit_3(tmp_path, edit, message):
    # today's README sample with one occurrence edited: read 1 part of 6 and passed before
    path = edited_sample(tmp_path, NAUO, edit)
    result = CliRunner().invoke(main, [path, "--no-cache"])
    assert result.exit_code == 3, result.output
    assert result.output.startswith(f"error: {path}: ") and message in result.output
    assert result.output.count("\n") == 1 and "Traceback" not in result.output


def test_external_reference_assembly_is_one_line_exit_3(tmp_path):
    path = write_step(
        tmp_path / "asm.step",
        {"plate": box((0, 0, 0), (10, 10, 1)), "block": box((0, 0, 0), (1, 1, 1))},
        [("plate", EYE), ("block", placement((0, 0, 1)))],
        external=True,
    )
    assert len(list(tmp_path.glob("*.stp"))) == 2  # the parts live in sibling files
    result = CliRunner().invoke(main, [path, "--no-cache"])
    assert result.exit_code == 3, result.output
    assert result.output.startswith(f"error: {path}: keeps its parts in other files (")
    assert "asmblock.stp" in result.output and "asmplate.stp" in result.output


def test_a_solid_outside_the_placed_products_refuses_the_file(tmp_path):
    # a second solid in the file that no placed product reaches (its representation dangling
    # from nothing): counted against the solids placed
    path = write_step(tmp_path / "one.step", {"a": box((0, 0, 0), (1, 1, 1))}, [("a", EYE)])
    text = open(path).read()
    brep = next(line for line in text.splitlines() if "MANIFOLD_SOLID_BREP" in line)
    number = brep.split("=")[0].strip()
    open(path, "w").write(text.replace(brep, f"{brep}\n#999999 = {brep.split('=', 1)[1]}"))
    assert number != "#999999"
    with pytest.raises(InputError, match=r"only 1 of its 2 solids are in a placed product"):
        read_step(path)


# --------------------------------------------------------------------------------------------
# Every unit a STEP file can declare


SI_UNITS = {"KILO": "km", "DECI": "dm", "CENTI": "cm", "MICRO": "um", "NANO": "nm", "$": "m"}
CONVERSION_UNITS = {"YARD": ("yd", 914.4), "MILE": ("mi", 1609344.0), "MIL": ("mil", 0.0254)}


def relabelled(tmp_path, unit: str) -> str:
    """A 2 x 1 x 1 box and a cube resting on it, in a file declaring ``unit`` (by editing the
    millimetre or inch unit OpenCASCADE wrote: the numbers stay, their unit changes)."""
    products = {"base": box((0, 0, 0), (2, 1, 1)), "cube": box((0, 0, 0), (1, 1, 1))}
    instances = [("base", EYE), ("cube", placement((0.5, 0, 1)))]
    if unit in CONVERSION_UNITS:
        text = open(write_step(tmp_path / "u.step", products, instances, unit="INCH")).read()
        text = text.replace("'INCH'", f"'{unit}'").replace(
            "(25.4,", f"({CONVERSION_UNITS[unit][1]!r},"
        )
    else:
        text = open(write_step(tmp_path / "u.step", products, instances)).read()
        prefix = "$" if unit == "$" else f".{unit}."
        text = text.replace("SI_UNIT(.MILLI.,.METRE.)", f"SI_UNIT({prefix},.METRE.)")
    path = tmp_path / f"{unit.strip('$') or 'm'}.step"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("unit", [*SI_UNITS, *CONVERSION_UNITS])
def test_every_declared_unit_is_read(tmp_path, unit):
    name = SI_UNITS.get(unit) or CONVERSION_UNITS[unit][0]
    asm = read_step(relabelled(tmp_path, unit))
    assert asm.unit == name
    base = dict((n, m) for n, m, _ in asm.items)["base"]
    assert np.allclose(base.bounds, [[0, 0, 0], [2, 1, 1]], atol=1e-9)


def test_files_in_km_dm_nm_yd_mi_and_mil_are_checked(tmp_path):
    # each reached report_unit and exited 4 before units.py had them
    for unit in ("KILO", "DECI", "NANO", "YARD", "MILE", "MIL"):
        path = relabelled(tmp_path, unit)
        result = CliRunner().invoke(main, [path, "--no-cache", "--format", "json"])
        assert result.exit_code == 0, (unit, result.output)
        doc = json.loads(result.stdout)
        assert doc["summary"]["units"] == (SI_UNITS.get(unit) or CONVERSION_UNITS[unit][0])
        assert [r["status"] for r in doc["results"]] == ["touching"]


# --------------------------------------------------------------------------------------------
# Deflection: a range that can be honoured


@pytest.mark.parametrize("deflection", ["1e-6", "1e-9"])
def test_a_deflection_too_fine_is_refused_before_meshing(deflection):
    # 1e-6 ran 51 s to a SIGSEGV at 1.7 GB; 1e-9 exited 4
    result = CliRunner().invoke(
        main, ["sample_meshes/assembly.step", "--step-deflection", deflection, "--no-cache"]
    )
    assert result.exit_code == 3, result.output
    assert "is finer than meshcheck can honour" in result.output and "or more" in result.output


def test_a_deflection_over_the_triangle_budget_is_refused_with_one_that_fits(tmp_path):
    path = pin_in_housing(tmp_path / "pin.step", hole=3.1, pin=3.0)
    with pytest.raises(InputError, match=r"would make about .* triangles \(budget 2000\)"):
        read_step(path, deflection=1e-4, max_triangles=2000)
