"""STEP input: names, instances, units, closed solids, tessellation error, cache, broken files.

Every STEP file here is written at test time by OpenCASCADE (cadquery-ocp, tests/step_writer.py)
with known answers: a clearance or a depth set in the CAD model, exact volumes from OpenCASCADE's
mass properties, placements chosen by the test.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from meshcheck.errors import InputError, MeshcheckWarning

pytest.importorskip("OCP")  # cadquery-ocp, the dev extra: writes the STEP files

from step_writer import (
    box,
    cut,
    cylinder,
    fillet,
    fuse,
    placement,
    volume,
    write_step,
)

from meshcheck.cli import main
from meshcheck.load import Body, load_bodies, mesh_digest
from meshcheck.load.step import (
    DEFAULT_DEFLECTION_MM,
    TessellationCache,
    close_mesh,
    read_step,
    step_unit,
    tessellation_key,
)
from meshcheck.pipeline import check_bodies

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
    return [
        Body(f"{path}#{n}", str(path), m, t) for n, m, t in read_step(str(path), **kwargs).items
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
    block = cut(block, cylinder(3.1, -1, 11, 2, 1), cylinder(1.0, 5, 12, -6, -6))
    path = write_step(tmp_path / "block.step", {"block": block}, [("block", EYE)])
    ((name, mesh, _),) = read_step(path).items
    assert name == "block"
    assert is_closed(mesh)
    # chords cut inside curved faces: a little less volume than the CAD solid, never more
    assert volume(block) * 0.998 < mesh.volume < volume(block)


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
    key = tessellation_key(data, DEFAULT_DEFLECTION_MM, 0.5)
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
    key = tessellation_key(open(files["bolts"], "rb").read(), DEFAULT_DEFLECTION_MM, 0.5)
    assert forger.get(key) is not None
    assert ours.get(key) is None
