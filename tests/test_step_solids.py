"""STEP pairs decided on the exact solids: every verdict and figure against OpenCASCADE's own
boolean and distance, instance pairs decided once, the same report however it was computed.

The oracle here is OpenCASCADE called directly on the file's placed solids in the world frame
(``BRepAlgoAPI_Common`` with its defaults, ``BRepExtrema_DistShapeShape``), or a closed form;
meshcheck decides each pair in its first solid's frame, on copies, through its own code path
(``meshcheck.verify.brep``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from step_writer import box, cut, cylinder, fuse, placement, wavy_ring, write_step

from meshcheck.cache import open_caches
from meshcheck.cli import main
from meshcheck.config import parse_test
from meshcheck.execute import LocalPool
from meshcheck.load import load_bodies
from meshcheck.pipeline import check_bodies
from meshcheck.settings import Settings
from meshcheck.verify import brep, solids, volumes

BOX_SIDES = str(Path(__file__).parent / "data" / "step" / "box_sides.STEP")
EYE = np.eye(4)
INCH = 25.4


def oracle(shape_a, shape_b, tolerance: float) -> tuple[str, float, float]:
    """(status without clearance, common volume, distance) of two placed solids, mm."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(BRepAlgoAPI_Common(shape_a, shape_b).Shape(), props)
    volume = max(props.Mass(), 0.0)
    distance = BRepExtrema_DistShapeShape(shape_a, shape_b).Value()
    if volume > math.pi / 6 * tolerance**3:
        return "interference", volume, distance
    return ("touching" if distance <= tolerance else "apart"), volume, distance


def node(body) -> str:
    return body.name.split("#", 1)[1]


# --------------------------------------------------------------------------------------------
# A real export: every candidate pair against the solids


def test_box_sides_every_pair_as_opencascade_decides_it():
    clearance = 0.05  # inches: some faces 0.0375 apart become clearance findings
    bodies = load_bodies([BOX_SIDES])
    result = check_bodies(bodies, clearance=clearance, jobs=1)
    assert len(result.checked_pairs) == 20
    found = {(f.a, f.b): f for f in result.findings}
    shapes = bodies[0].brep.by_node()
    statuses = []
    for a, b in result.checked_pairs:
        finding = found.get((a, b))
        tolerance = finding.tolerance if finding else 1e-5 * INCH  # below any gap found here
        status, volume, distance = oracle(
            shapes[a.split("#", 1)[1]], shapes[b.split("#", 1)[1]], tolerance * INCH
        )
        if status == "apart":
            status = "clearance" if distance <= clearance * INCH else "clear"
        statuses.append(status)
        assert (finding.status if finding else "clear") == status, (a, b)
        if status == "interference":
            assert finding.volume * INCH**3 == pytest.approx(volume, rel=1e-6)
            assert finding.depth == pytest.approx(0.0075, rel=1e-6)  # the sides' 0.0075 in seat
            assert finding.tolerance < 1e-3  # the solids' own, not the deflections'
        if status == "clearance":
            assert finding.distance * INCH == pytest.approx(distance, rel=1e-6)
    assert statuses.count("interference") == 8 and statuses.count("touching") == 8
    assert statuses.count("clearance") == 4  # each distance checked against BRepExtrema


def test_no_valid_solid_of_a_real_export_is_reported_open():
    # every solid OpenCASCADE's checker calls valid is meshed closed, and its findings carry the
    # solid's figures: no surface-only verdict, every interference with its depth and volume
    from OCP.BRepCheck import BRepCheck_Analyzer

    bodies = load_bodies([BOX_SIDES])
    shapes = bodies[0].brep.by_node()
    valid = [b for b in bodies if BRepCheck_Analyzer(shapes[node(b)]).IsValid()]
    assert len(valid) == 10
    assert all(b.is_closed for b in valid)
    findings = check_bodies(bodies, jobs=1).findings
    assert len(findings) == 16
    assert not any(f.verdict.is_surface_only for f in findings)
    interferences = [f for f in findings if f.status == "interference"]
    assert len(interferences) == 8
    assert all(f.depth > 0 and f.volume > 0 for f in interferences)


# --------------------------------------------------------------------------------------------
# Figures of the solid, in closed form


def test_clearance_is_the_solids_distance_not_the_chords(tmp_path):
    # 0.2 mm radial clearance: the chords of a 0.005 mm tessellation read up to 0.01 mm off
    housing = cut(box((-8, -8, 0), (8, 8, 6)), cylinder(3.2, -1, 7))
    path = write_step(
        tmp_path / "screw.step",
        {"housing": housing, "screw": cylinder(3.0, -2, 8)},
        [("housing", EYE), ("screw", placement(angle_deg=7.0))],
    )
    (finding,) = check_bodies(load_bodies([path]), clearance=0.25, jobs=1).findings
    assert finding.status == "clearance"
    assert finding.distance == pytest.approx(0.2, rel=1e-9)
    p, q = finding.closest
    assert np.linalg.norm(p - q) == pytest.approx(0.2, rel=1e-9)
    assert np.hypot(*p[:2]) == pytest.approx(3.2, rel=1e-9)  # on the hole, exactly


def test_clash_tests_decide_step_pairs_on_the_solids_at_their_own_tolerance(tmp_path):
    # two tests on one screw in its housing, at two tolerances (two verifications): each judges
    # the B-rep's verdict, the 0.2 mm gap exact
    housing = cut(box((-8, -8, 0), (8, 8, 6)), cylinder(3.2, -1, 7))
    path = write_step(
        tmp_path / "screw.step",
        {"housing": housing, "screw": cylinder(3.0, -2, 8)},
        [("housing", EYE), ("screw", placement(angle_deg=7.0))],
    )
    tests = [
        parse_test("fit:*screw:*housing:clearance=0.25:tolerance=0.001"),
        parse_test("tight:*screw:*housing:clearance=0.1"),
    ]
    (finding,) = check_bodies(load_bodies([path]), jobs=1, tests=tests).findings
    assert (finding.test, finding.status) == ("fit", "clearance")
    assert finding.distance == pytest.approx(0.2, rel=1e-9)
    assert finding.tolerance == 0.001


def test_interference_volume_and_location_are_the_common_solids(tmp_path):
    # a 2 mm cube sunk 0.5 mm into a plate, the cube rotated a quarter turn about z and placed
    # away from the origin: volume 2 mm3, centroid and box of the 2 x 2 x 0.5 slab
    path = write_step(
        tmp_path / "sunk.step",
        {"plate": box((0, 0, 0), (20, 20, 4)), "cube": box((-1, -1, 0), (1, 1, 2))},
        [("plate", EYE), ("cube", placement((12.5, 7.5, 3.5), angle_deg=90.0))],
    )
    (finding,) = check_bodies(load_bodies([path]), jobs=1).findings
    assert finding.status == "interference"
    assert finding.volume == pytest.approx(2.0, rel=1e-9)
    assert finding.depth == pytest.approx(0.5, rel=1e-6)
    assert np.allclose(finding.location.centroid, [12.5, 7.5, 3.75], atol=1e-9)
    assert np.allclose(finding.location.lower, [11.5, 6.5, 3.5], atol=1e-9)
    assert np.allclose(finding.location.upper, [13.5, 8.5, 4.0], atol=1e-9)
    solid = trimesh.Trimesh(finding.solid.vertices, finding.solid.faces)
    assert solid.volume == pytest.approx(2.0, rel=1e-6)  # the shared solid, drawn where it is


@pytest.mark.parametrize(
    "waves, amplitude",
    [
        (4, 0.1),  # fixed-order Gauss: 6.3e-6 off, its estimate 6e-8
        (24, 0.5),  # Gauss-Kronrod: 4.4e-6 off, its estimate 3e-5; as B-spline faces, 2.4e-9
    ],
)
def test_volumes_are_the_solids_where_the_integration_stalls_on_a_face(waves, amplitude):
    # A ring's wall revolved from a 58-knot B-spline; the oracle is Pappus on the profile.
    ring, exact = wavy_ring(2.0, 3.0, 6.0, amplitude=amplitude, waves=waves)
    assert volumes.volume(ring) == pytest.approx(exact, rel=1e-7)


def test_a_volume_whose_faces_cannot_be_converted_keeps_its_first_integral(monkeypatch):
    # The conversion raising is injected: no solid at hand makes OpenCASCADE refuse it.
    import OCP.BRepBuilderAPI
    from OCP.Standard import Standard_Failure

    def refuse(*args):
        raise Standard_Failure("BRepBuilderAPI_NurbsConvert")

    ring, exact = wavy_ring(2.0, 3.0, 6.0, amplitude=0.5, waves=24)
    monkeypatch.setattr(OCP.BRepBuilderAPI, "BRepBuilderAPI_NurbsConvert", refuse)
    assert volumes.volume(ring) == pytest.approx(exact, rel=1e-5)  # 4.4e-6 off, as integrated


def test_an_interference_has_the_shared_solids_volume_where_the_integration_stalls():
    ring, exact = wavy_ring(2.0, 3.0, 6.0, amplitude=0.1, waves=4)
    found = solids.decide(ring, box((-4, -4, -1), (4, 4, 7)), tolerance=1e-4)  # buried in it
    assert (found.status, found.volume) == ("interference", pytest.approx(exact, rel=1e-7))


def test_a_solid_meshed_open_is_still_decided_on_its_b_rep(tmp_path):
    # The tessellation of a valid solid loses a triangle (as exporters' seams can): the pair is
    # still decided on the solids, with their depth and volume.
    path = write_step(
        tmp_path / "press.step",
        {
            "housing": cut(box((-6, -6, 0), (6, 6, 4)), cylinder(3.0, -1, 5)),
            "pin": cylinder(3.01, -1, 5),
        },
        [("housing", EYE), ("pin", placement(angle_deg=7.0))],
    )
    bodies = load_bodies([path])
    holed = trimesh.Trimesh(bodies[0].mesh.vertices, bodies[0].mesh.faces[1:], process=False)
    bodies[0] = dataclasses.replace(bodies[0], mesh=holed)
    assert not bodies[0].is_closed
    (finding,) = check_bodies(bodies, jobs=1).findings
    annulus = math.pi * (3.01**2 - 3.0**2) * 4.0
    assert finding.status == "interference"
    assert finding.volume == pytest.approx(annulus, rel=1e-6)
    assert finding.depth == pytest.approx(0.01, rel=1e-3)


# --------------------------------------------------------------------------------------------
# Instances decided once; the same report however it was computed


def fastened(path) -> str:
    """A plate with three holes, a bolt line to line in each and a nut under each bolt: three
    bolt/nut pairs at one relative placement (the bolts turned alike), the others apart."""
    holes = (-20.0, 0.0, 20.0)
    plate = cut(box((-30, -10, 0), (30, 10, 6)), *[cylinder(2.5, -1, 7, x, 0) for x in holes])
    bolt = fuse(cylinder(4.0, 6.0, 9.0), cylinder(2.5, -6.0, 6.0))
    nut = cut(box((-4, -4, -4), (4, 4, 0)), cylinder(2.5, -5, 1))
    instances = [("plate", EYE)]
    for x in holes:
        instances += [("bolt", placement((x, 0, 0), 30.0)), ("nut", placement((x, 0, 0), 30.0))]
    return write_step(path, {"plate": plate, "bolt": bolt, "nut": nut}, instances)


def press_fit(path) -> str:
    """A pin 0.01 mm larger than its hole, in a housing: one interference."""
    return write_step(
        path,
        {
            "housing": cut(box((-6, -6, 0), (6, 6, 4)), cylinder(3.0, -1, 5)),
            "pin": cylinder(3.01, -1, 5),
        },
        [("housing", placement((100, 0, 0))), ("pin", placement((100, 0, 0), 7.0))],
    )


def pair_entries(folder) -> int:
    return len(list(Path(folder).glob("pairs-v*/**/*.json")))


def test_pairs_of_the_same_products_at_the_same_relative_placement_are_decided_once(
    tmp_path, monkeypatch
):
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "test-secret")
    path = fastened(tmp_path / "fastened.step")
    bodies = load_bodies([path])
    caches = open_caches(str(tmp_path / "cache"))
    result = check_bodies(bodies, jobs=1, caches=caches)
    statuses = sorted((node(b), f.status) for f in result.findings for b in bodies if b.name == f.a)
    assert [s for _, s in statuses] == ["touching"] * 9  # 3 bolt/nut, 3 bolt/plate, 3 nut/plate
    # one verdict for the three bolt/nut pairs, one for each bolt/plate and nut/plate pair
    assert pair_entries(tmp_path / "cache") == 7


def test_reports_are_the_same_cold_warm_and_in_workers(tmp_path, monkeypatch):
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "test-secret")
    path = fastened(tmp_path / "fastened.step")
    press = press_fit(tmp_path / "press.step")
    args = [path, press, "--format", "json", "--clearance", "1"]
    cache = ["--cache-dir", str(tmp_path / "cache")]
    outputs = [
        CliRunner().invoke(main, [*args, "--no-cache", "-j", "1"]),
        CliRunner().invoke(main, [*args, *cache, "-j", "2"]),
        CliRunner().invoke(main, [*args, *cache, "-j", "1"]),  # warm
    ]
    assert [r.exit_code for r in outputs] == [1, 1, 1], outputs[0].output
    assert outputs[0].stdout == outputs[1].stdout == outputs[2].stdout
    statuses = [r["status"] for r in json.loads(outputs[0].stdout)["results"]]
    assert statuses.count("interference") == 1
    # and in worker processes (the cost model keeps pairs this few in this process)
    monkeypatch.setattr(brep, "PAIR_SECONDS", 100.0)
    bodies = load_bodies([path, press])
    here = check_bodies(bodies, jobs=1, clearance=1.0).findings
    with LocalPool(2) as pool:
        there = check_bodies(bodies, jobs=2, clearance=1.0, executor=pool).findings
    assert here == there
    assert [f.verdict.solid.vertices.tobytes() for f in here if f.solid] == [
        f.verdict.solid.vertices.tobytes() for f in there if f.solid
    ]


def test_a_verdict_does_not_depend_on_meshes_earlier_pairs_left_on_the_faces():
    # A worker decides many pairs on the same products; the shared solid's faces can be a
    # product's own (the cylinder's top here), and a face keeps the finest triangulation any
    # call gave it. The verdict, its seeds and its drawing must not depend on that history.
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    pin, block = cylinder(5.0, 0.0, 10.0), box((-6, -6, 5), (6, 6, 11))
    first = solids.decide(pin, block, tolerance=1e-3)
    BRepMesh_IncrementalMesh(pin, 5e-4, False, 0.02, False)  # what an earlier pair may leave
    again = solids.decide(pin, block, tolerance=1e-3)
    assert first.status == again.status == solids.Verdict.INTERFERENCE
    assert (first.depth, first.volume) == (again.depth, again.volume)
    assert [a.tobytes() for a in first.solid] == [a.tobytes() for a in again.solid]


def _every_candidate_classified(shape) -> float:
    """The largest ball of ``solids._largest_ball``'s candidates, every one classified."""
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.IntCurvesFace import IntCurvesFace_ShapeIntersector
    from OCP.TopAbs import TopAbs_IN

    best = 0.0
    for solid in solids._solids(shape):
        classifier, intersector = (
            BRepClass3d_SolidClassifier(solid),
            IntCurvesFace_ShapeIntersector(),
        )
        intersector.Load(solid, 1e-9)
        for point, inward in solids._seeds(solid):
            exit_at = solids._ray_exit(intersector, point, inward)
            if exit_at is None:
                continue
            centre = point + 0.5 * exit_at * inward
            classifier.Perform(solids._pnt(centre), 1e-12)
            if classifier.State() == TopAbs_IN:
                best = max(best, 2.0 * solids._distance_to_surface(solid, centre))
    return best


@pytest.mark.parametrize(
    "make",
    [
        lambda: box((0, 0, 0), (3, 1, 2)),
        lambda: cut(cylinder(3.0, 0.0, 2.0), cylinder(2.5, -1.0, 3.0)),  # a tube
        lambda: fuse(box((0, 0, 0), (4, 1, 1)), box((0, 0, 0), (1, 3, 1))),  # an L
        lambda: cut(cylinder(2.0, 0.0, 1.0), cylinder(2.0, -1.0, 2.0, x=1.2)),  # a crescent
        lambda: fuse(box((0, 0, 0), (1, 1, 1)), box((3, 0, 0), (5, 2, 2))),  # two solids
        # a plate and a fin: the longest rays (10 mm, along the fin) hold 0.67 mm balls, the
        # plate's 1 mm rays 1 mm balls
        lambda: fuse(box((0, 0, 0), (10, 10, 1)), box((3.23, 0, 0), (3.43, 10, 9))),
    ],
)
def test_the_ball_is_the_largest_of_its_candidates_inside(make):
    shape = make()
    assert solids._largest_ball(shape) == _every_candidate_classified(shape) > 0.0


# --------------------------------------------------------------------------------------------
# The distance of two solids that share no volume, on the faces near each other only


def _plate():
    """A plate with a 3.2 mm hole and a pocket."""
    return cut(box((-10, -10, 0), (10, 10, 4)), cylinder(3.2, -1.0, 5.0), box((4, 4, 2), (8, 8, 5)))


def _bolt():
    """A 3 mm shank under a 5 mm head."""
    return fuse(cylinder(3.0, -2.0, 6.0), cylinder(5.0, 6.0, 8.0))


def _placed(shape, matrix):
    return shape.Moved(solids._location(matrix))


def _extrema(found) -> tuple[float, list]:
    distance, points = found
    return distance, [(a.tolist(), b.tolist()) for a, b in points]


def _shares_volume(shape_a, shape_b) -> bool:
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common

    return volumes.volume(BRepAlgoAPI_Common(shape_a, shape_b).Shape()) > 0.0


@pytest.mark.parametrize(
    "other",
    [
        _placed(_bolt(), placement((0.1, 0.0, 0.0))),  # in the hole, 0.1 from its wall
        _placed(_bolt(), placement((0.2, 0.0, -1.9))),  # on the wall, the head 0.1 over the top
        _placed(_bolt(), placement((0.0, 0.0, -2.0))),  # the head resting on the plate
        box((5, 5, 2.5), (7, 7, 3.5)),  # in the pocket, its box inside the plate's
        _placed(_plate(), placement((0.0, 20.001, 0.0), 180.0)),  # side by side
    ],
)
def test_the_distance_on_near_faces_is_the_solids_distance(other):
    plate = _plate()
    assert not _shares_volume(plate, other)
    whole = _extrema(solids._distance(plate, other))
    for may_nest in (False, True):
        assert _extrema(solids._boundary_distance(plate, other, may_nest=may_nest)) == whole
        assert _extrema(solids._boundary_distance(other, plate, may_nest=may_nest)) == _extrema(
            solids._distance(other, plate)
        )


@settings(derandomize=True, deadline=None, max_examples=30)
@given(
    st.floats(-12.0, 12.0),
    st.floats(-12.0, 12.0),
    st.floats(0.0, 2.0),
    st.floats(0.0, 180.0),
    st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
)
def test_the_distance_on_near_faces_is_the_solids_distance_over_the_plate(x, y, gap, angle, axis):
    tilted = _placed(_bolt(), placement((x, y, 0.0), angle, axis))
    lowest = solids._box(tilted)[0][2]
    bolt = _placed(tilted, placement((0.0, 0.0, 4.0 + 1e-3 + gap - lowest)))
    assert _extrema(solids._boundary_distance(_plate(), bolt, may_nest=False)) == _extrema(
        solids._distance(_plate(), bolt)
    )


@settings(derandomize=True, deadline=None, max_examples=30)
@given(st.floats(0.0, 0.19), st.floats(0.0, 2 * math.pi), st.floats(-1.9, 2.0), st.floats(0, 90))
def test_the_distance_on_near_faces_is_the_solids_distance_in_the_hole(off, towards, z, spin):
    move = (off * math.cos(towards), off * math.sin(towards), z)
    bolt = _placed(_bolt(), placement(move, spin))
    assert _extrema(solids._boundary_distance(_plate(), bolt)) == _extrema(
        solids._distance(_plate(), bolt)
    )


def test_a_solid_inside_the_other_is_at_distance_0_when_no_boolean_said_otherwise():
    # As solids: OpenCASCADE's distance finds one inside the other (0), not in compounds.
    plate, inside = solids._solids(_plate())[0], solids._solids(box((-9, -9, 1), (-8, -8, 2)))[0]
    assert _extrema(solids._boundary_distance(plate, inside)) == _extrema(
        solids._distance(plate, inside)
    )
    assert solids._boundary_distance(plate, inside)[0] == 0.0
    assert solids._boundary_distance(inside, plate)[0] == 0.0


def test_pairs_timed_here_then_sent_to_workers_give_the_same_findings(tmp_path, monkeypatch):
    # With the workers' start free and no expected seconds a pair, the fixed estimate keeps the
    # pairs here; the first pair's measured seconds then send the rest to the workers.
    from meshcheck.verify import batch

    path = fastened(tmp_path / "fastened.step")
    bodies = load_bodies([path])
    here = check_bodies(bodies, jobs=1, clearance=1.0).findings
    monkeypatch.setattr(brep, "PAIR_SECONDS", 0.0)
    monkeypatch.setattr(brep, "WORKER_SECONDS", 0.0)
    monkeypatch.setattr(batch, "POOL_SECONDS", 0.0)
    answers = []
    real = brep._pays_in_workers

    def pays(executor, pairs, seconds=None):
        answers.append((seconds is None, real(executor, pairs, seconds)))
        return answers[-1][1]

    monkeypatch.setattr(brep, "_pays_in_workers", pays)
    with LocalPool(2) as pool:
        there = check_bodies(bodies, jobs=2, clearance=1.0, executor=pool).findings
        assert pool.is_started  # the pairs after the first went to its worker
    assert answers[0] == (True, False)  # the fixed estimate: here
    assert answers[1] == (False, True)  # the first pair's seconds: the rest in workers
    assert here == there


def test_pairs_go_to_a_ready_worker_as_the_screen_makes_them(tmp_path):
    """With every core's process started and OpenCASCADE loaded (``_streams``), each pair the
    screen sends to the B-rep goes to the idle worker at once: the worker has pairs before this
    process does its own work (``meanwhile``) and takes any. The findings are the same."""
    from meshcheck.execute import Task

    paths = [fastened(tmp_path / "fastened.step"), press_fit(tmp_path / "press.step")]
    bodies = load_bodies(paths)
    here = check_bodies(bodies, jobs=1, clearance=1.0).findings
    sent_before = []
    with LocalPool(2) as pool:
        pool.prepare(brep.PREPARE)
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        assert brep._streams(pool)
        worker = pool.workers[0]

        def meanwhile():
            sent_before.append({key[0] for key in worker.keys if isinstance(key, tuple)})

        pairs = np.array([(i, j) for i in range(len(bodies)) for j in range(i + 1, len(bodies))])
        settings = Settings(clearance=1.0)
        findings, _, _ = brep.decide_on_brep(
            bodies, pairs, np.ones(len(pairs), bool), settings, executor=pool, meanwhile=meanwhile
        )
        there = check_bodies(bodies, jobs=2, clearance=1.0, executor=pool).findings
    assert sent_before == [{"brep"}]  # once, with pairs already sent to the worker
    assert here == there
    assert {(f.a, f.b, f.status) for f in findings} == {(f.a, f.b, f.status) for f in here}


def test_the_screen_gives_each_pair_the_job_it_gives_it_alone(tmp_path):
    """The screen makes the jobs whose meshes meet first, then measures the others: each
    pair's job (its key, whether the solids may overlap) or None is what screening that pair
    on its own gives (``pair.surface_distance`` to the reach, the first triangle pair within
    the two deflections answering)."""
    from meshcheck.units import METRES
    from meshcheck.verify.pair import surface_distance

    paths = [fastened(tmp_path / "fastened.step"), press_fit(tmp_path / "press.step")]
    bodies = load_bodies(paths)
    settings = Settings(clearance=1.0)
    pairs = np.array([(i, j) for i in range(len(bodies)) for j in range(i + 1, len(bodies))])
    near = np.arange(len(pairs)) % 3 != 0  # some proven apart by their pieces
    screened = dict(brep._screened(bodies, pairs, near, settings))
    assert sorted(screened) == list(range(len(pairs)))
    for k, pair in enumerate(pairs):
        job = brep._pair_job(bodies, pair, settings)
        a, b = bodies[job.first], bodies[job.second]
        deflections = a.deflection + b.deflection
        reach = job.tolerance_report + deflections + 1.0 * 1e-3 / METRES[a.units]
        distance = surface_distance(
            a.world, b.world, reach=reach, surfaces_apart=not near[k], enough=deflections
        )
        if distance > reach:
            assert screened[k] is None, k
        else:
            expected = brep._keyed(job, may_overlap=distance <= deflections)
            assert (screened[k].key, screened[k].may_overlap) == (
                expected.key,
                expected.may_overlap,
            )
    assert sum(job is not None for job in screened.values()) >= 4


def test_the_b_rep_stage_does_its_own_work_once_with_or_without_pairs(tmp_path):
    bodies = load_bodies([fastened(tmp_path / "fastened.step")])
    settings = Settings()
    calls = []
    for pairs in (np.zeros((0, 2), np.int64), np.array([(0, 1), (0, 2), (1, 2)])):
        brep.decide_on_brep(
            bodies, pairs, np.ones(len(pairs), bool), settings, meanwhile=lambda: calls.append(1)
        )
        assert len(calls) == 1
        calls.clear()


def test_pairs_left_to_the_started_worker_grow_the_pool_when_the_rest_repays_it(monkeypatch):
    """Pairs left to the workers already started (``_by_started_workers``: this process has
    not loaded OpenCASCADE) stay with them while the rest would not repay starting another
    (``WORKER_SECONDS``); once it would, the pool's others start and take part."""
    from meshcheck.execute import Task

    def run(executor, chosen, done=0, **where):
        return executor.map("meshcheck.execute:sleep_then_pid", chosen, **where)

    tasks = [Task((0.2,)) for _ in range(8)]
    with LocalPool(2) as pool:
        (first,) = pool.map("meshcheck.execute:sleep_then_pid", [Task((0.0,))])
        assert brep._by_started_workers(run, pool, tasks) == [first] * 8  # 1.6 s: not enough
        assert len(pool.workers) == 1
        monkeypatch.setattr(brep, "WORKER_SECONDS", 0.0)
        pids = brep._by_started_workers(run, pool, tasks)
        assert pids[0] == first and len(set(pids)) == 2 and len(pool.workers) == 2


@pytest.mark.linux_only  # a twin is killed through a pidfd: none elsewhere
def test_pairs_left_to_a_worker_and_its_twin_are_one_map_over_both():
    """With the early worker's twin in reserve, every core has a worker: the pairs go to both
    in one map (no batches to measure), and no other worker starts."""
    from meshcheck.execute import Task, start_early, take_early

    def run(executor, chosen, done=0, **where):
        calls.append(len(chosen))
        return executor.map("meshcheck.execute:sleep_then_pid", chosen, **where)

    calls: list = []
    start_early("p", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=brep.PREPARE, twin=True)
    with LocalPool(2) as pool:
        first = take_early("p", pool)
        pids = brep._by_started_workers(run, pool, [Task((0.2,)) for _ in range(6)])
        assert calls == [6] and first in pids and len(set(pids)) == 2
        assert pool.started == 2


def test_the_solids_travel_to_workers_as_brep_text(tmp_path):
    # the text a worker reads back is the product as read, with no triangulation
    path = fastened(tmp_path / "fastened.step")
    body = next(b for b in load_bodies([path]) if node(b) == "bolt_1")
    text = body.brep.product_text("bolt_1")
    assert text == body.brep.product_text("bolt")  # one product, one text
    assert b"Triangulations 0" in text
    store = {("brep", "p"): text}
    shape = solids._shape(store, ("brep", "p"))
    assert solids.is_closed_solid(shape)
    assert solids._shape(store, ("brep", "p")) is shape  # read once per process


def test_workers_start_loading_opencascade_for_large_step_files_only(tmp_path):
    small, large = tmp_path / "small.step", tmp_path / "large.STP"
    small.write_bytes(b"x" * 1000)
    large.write_bytes(b"x" * brep.PREPARE_BYTES)
    for paths, prepared in (
        ([str(small), str(tmp_path / "missing.step")], False),  # the loader reports it
        ([str(large)], True),
    ):
        with LocalPool(2) as pool:
            brep.prepare_workers(pool, paths)
            assert (len(pool.workers), pool.prepared) == (
                (1, {brep.PREPARE}) if prepared else (0, frozenset())
            )
