"""Mechanisms from mesh files: ``[[joint]]`` tables turn STL parts into a mechanism
posed and swept as a URDF robot is; a door on a hinge with a stop against the closed form, a
slide into a block, and every mistake in the tables one line with exit 2.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from meshes import box, box_between
from test_hostile_inputs import measured
from test_sweep import door

from meshcheck.cli import main
from meshcheck.errors import ConfigError, ExitStatus
from meshcheck.load import load_assembly, load_bodies
from meshcheck.motion import MAX_JOINTS, Motion, checked_joints, parse_pose
from meshcheck.settings import Settings
from meshcheck.sweep import sweep_bodies

# The door of tests/test_sweep.py in millimetres: 1000 long, T thick, hinged about z through the
# origin; the stop spans x 500..800, y 300..500. Opening, the door's face y' = T/2 first meets
# the stop's corner (BX, CY) at a* = acos(T / 2 / R) - atan2(BX, CY), R = |(BX, CY)|.
T, BX, CY = 100.0, 800.0, 300.0
STOP_ANGLE = math.acos(T / 2 / math.hypot(BX, CY)) - math.atan2(BX, CY)


def door_files(tmp_path) -> list[str]:
    box_between((0, -T / 2, -100), (1000, T / 2, 100)).export(tmp_path / "door.stl")
    box_between((500, 300, -100), (800, 500, 100)).export(tmp_path / "stop.stl")
    box_between((-85, -25, -100), (-35, 25, 100)).export(tmp_path / "frame.stl")
    return [str(tmp_path / n) for n in ("door.stl", "stop.stl", "frame.stl")]


def hinge(upper: str = "90deg", **extra) -> dict:
    table = {"name": "hinge", "parent": "frame.stl", "child": "door.stl", "type": "revolute",
             "axis": [0, 0, 1], "origin": [0, 0, 0], "range": ["-30deg", upper]}  # fmt: skip
    return {**table, **extra}


def toml(joints: list[dict]) -> str:
    def value(v):
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return f'"{v}"' if isinstance(v, str) else repr(v)

    return "".join(
        "[[joint]]\n" + "".join(f"{k} = {value(v)}\n" for k, v in j.items()) for j in joints
    )


#: Touching tolerance of the sweeps, mm: a witness may touch up to TOL / 800 rad short of the
#: stop angle (the door's face approaches the corner at 853 mm per radian there).
TOL = 1e-3


def sweep(files, joints, **motion) -> dict:
    settings = Settings(
        tolerance=TOL, motion=Motion(sweep=(), joints=checked_joints(joints), **motion)
    )
    assembly = load_assembly(files, motion=settings.motion)
    (robot,) = sweep_bodies(assembly.bodies, assembly.mechanisms, settings)
    return {(p.a.rsplit("/", 1)[-1], p.b.rsplit("/", 1)[-1]): p for p in robot.pairs}


def run(tmp_path, files, joints, *args):
    config = tmp_path / "meshcheck.toml"
    config.write_text(toml(joints))
    return CliRunner().invoke(
        main, [*files, "--config", str(config), "--no-cache", "-j", "1", *args]
    )


# ------------------------------------------------------------------------------------------
# Known answers


@pytest.mark.parametrize("margin", [1e-3, 1e-4])
def test_door_stop_angle_from_stl_files_is_found_within_the_tolerance(tmp_path, margin):
    """Range just short of the closed-form stop angle: never (proven); just past it: sometimes,
    with a witness between the stop angle and the range's end, as for the URDF door."""
    files = door_files(tmp_path)
    short = sweep(files, [hinge(STOP_ANGLE - margin)], resolution=margin / 10)
    assert short["door.stl", "stop.stl"].status == "never"
    assert short["door.stl", "frame.stl"].is_adjacent
    assert ("frame.stl", "stop.stl") not in short  # nothing moves them: the check judges them
    past = sweep(files, [hinge(STOP_ANGLE + margin)], resolution=margin / 10)
    pair = past["door.stl", "stop.stl"]
    assert pair.status == "sometimes" and pair.verdict in ("interference", "touching")
    assert not pair.is_adjacent
    assert STOP_ANGLE - TOL / 800 <= pair.witness["hinge"] <= STOP_ANGLE + margin


def test_a_slide_into_a_block_is_found_and_short_of_it_proven_clear(tmp_path):
    box_between((0, 0, 0), (100, 20, 20)).export(tmp_path / "slider.stl")
    box_between((150, -10, -10), (200, 30, 30)).export(tmp_path / "block.stl")
    box_between((0, -40, 0), (200, -30, 20)).export(tmp_path / "rail.stl")
    files = [str(tmp_path / n) for n in ("slider.stl", "block.stl", "rail.stl")]
    slide = {"name": "slide", "parent": "rail.stl", "child": "slider.stl", "type": "prismatic",
             "axis": [2, 0, 0]}  # fmt: skip
    clear = sweep(files, [{**slide, "range": [0, 49.9]}], resolution=1e-3)
    assert clear["block.stl", "slider.stl"].status == "never"
    hit = sweep(files, [{**slide, "range": [0, 60]}])
    pair = hit["block.stl", "slider.stl"]
    assert pair.status == "sometimes" and 50.0 - 1e-6 <= pair.witness["slide"] <= 60.0


def test_a_pose_moves_the_child_parts_about_the_axis(tmp_path):
    """At hinge=90deg the door stands along +y, clear of the stop; at 30deg it is buried in
    the stop's corner: one interference, exit 1. The door meets its frame (adjacent)."""
    files = door_files(tmp_path)
    motion = Motion(pose=parse_pose("hinge=90deg"), joints=checked_joints([hinge()]))
    (door, stop, frame) = load_bodies(files, motion=motion)
    lower, upper = door.world.bounds
    np.testing.assert_allclose(lower[:2], [-T / 2, 0.0], atol=1e-9)
    np.testing.assert_allclose(upper[:2], [T / 2, 1000.0], atol=1e-9)
    assert np.array_equal(stop.transform, np.eye(4)) and np.array_equal(frame.transform, np.eye(4))

    at_30 = run(tmp_path, files, [hinge()], "--pose", "hinge=30deg", "--format", "json")
    assert at_30.exit_code == ExitStatus.FAILED, at_30.output
    assert '"status": "interference"' in at_30.stdout and "stop.stl" in at_30.stdout
    at_10 = run(tmp_path, files, [hinge()], "--pose", "hinge=10deg")
    assert at_10.exit_code == 0, at_10.output
    beyond = run(tmp_path, files, [hinge()], "--pose", "hinge=100deg")
    assert beyond.exit_code == ExitStatus.USAGE and "beyond its limits" in beyond.stderr


def test_the_sweep_reports_carry_the_witness_pose_that_the_check_confirms(tmp_path):
    """--sweep from the command line: the JSON report's sweep lists each pair with the joint
    values of its witness; checking at that pose finds the door in the stop (exit 1). The text
    and Markdown reports name the pair and the pose as --pose takes it."""
    files = door_files(tmp_path)
    done = run(tmp_path, files, [hinge()], "--sweep", "--format", "json")
    assert done.exit_code == ExitStatus.FAILED, done.output  # the door hits its stop
    assert "2 link pairs (1 adjacent): 0 never, 2 sometimes" in done.stderr
    (robot,) = json.loads(done.stdout)["sweeps"]
    assert robot["counts"] == {"never": 0, "sometimes": 2, "always": 0, "undecided": 0}
    pairs = {(p["a"].rsplit("/", 1)[-1], p["b"].rsplit("/", 1)[-1]): p for p in robot["pairs"]}
    stop = pairs["door.stl", "stop.stl"]
    assert stop["status"] == "sometimes" and not stop["adjacent"] and stop["joints"] == ["hinge"]
    angle = stop["pose"]["hinge"]
    assert STOP_ANGLE <= angle <= math.radians(90)
    at_witness = run(tmp_path, files, [hinge()], "--pose", f"hinge={angle!r}", "--format", "json")
    assert at_witness.exit_code == ExitStatus.FAILED, at_witness.output
    (finding,) = [f for f in json.loads(at_witness.stdout)["results"] if not f["approved"]]
    assert finding["status"] == stop["verdict"] and finding["b"].endswith("stop.stl")

    text = run(tmp_path, files, [hinge()], "--sweep").stdout
    shown = f"door.stl / stop.stl interference at --pose hinge={angle:.9g}"
    assert shown in " ".join(text.split())
    markdown = run(tmp_path, files, [hinge()], "--sweep", "--format", "markdown").stdout
    assert "| sometimes (adjacent) |" in markdown and "stop\\.stl" in markdown


def test_a_collision_in_motion_fails_the_run_unless_approved(tmp_path):
    """A mechanism's parts colliding within the declared range fail the run (exit 1) in every
    format, named with the witness pose, even with --quiet; an approval rule for the two parts
    lets it pass, saying why; a range short of the stop passes; the door meeting its frame
    (adjacent) never fails it."""
    files = door_files(tmp_path)
    failing = {}
    for fmt in ("text", "json", "junit", "sarif", "github", "markdown"):
        out = run(tmp_path, files, [hinge()], "--sweep", "--format", fmt, "--quiet")
        assert out.exit_code == ExitStatus.FAILED, (fmt, out.output)
        failing[fmt] = out.stdout
    assert "1 colliding in motion" in failing["text"] and "FAIL sweep sometimes" in failing["text"]
    assert "| FAIL sometimes |" in failing["markdown"]
    shown = run(tmp_path, files, [hinge()], "--sweep").stdout  # failing first, then the others
    assert shown.index("FAIL sweep") < shown.index("(approved: adjacent)")
    assert "hinge=" in failing["text"] and "frame.stl" not in failing["text"].split("FAIL ")[1]
    doc = json.loads(failing["json"])
    (robot,) = doc["sweeps"]
    fails = {p["b"].rsplit("/", 1)[-1]: p["failed"] for p in robot["pairs"]}
    assert fails == {"stop.stl": True, "frame.stl": False}
    assert doc["summary"]["failed_in_motion"] == 1 and not doc["summary"]["passed"]
    assert 'failures="1"' in failing["junit"] and "[sweep]" in failing["junit"]
    (sarif_run,) = json.loads(failing["sarif"])["runs"]
    assert [r["message"]["text"].startswith("in motion:") for r in sarif_run["results"]] == [True]
    assert "::error " in failing["github"] and "in motion" in failing["github"]

    config = tmp_path / "meshcheck.toml"
    approved_config = toml([hinge()]) + (
        '[[ignore]]\na = "*door.stl"\nb = "*stop.stl"\nreason = "the stop is the design"\n'
    )
    config.write_text(approved_config)
    approved = CliRunner().invoke(
        main, [*files, "--config", str(config), "--no-cache", "-j", "1", "--sweep"]
    )
    assert approved.exit_code == 0, approved.output
    assert "(approved: the stop is the design)" in " ".join(approved.stdout.split())
    short = run(tmp_path, files, [hinge(STOP_ANGLE - 1e-3)], "--sweep")
    assert short.exit_code == 0, short.output


# ------------------------------------------------------------------------------------------
# Mistakes: one line, exit 2


def _two_doors(tmp_path) -> list[str]:
    files = door_files(tmp_path)
    box((10, 10, 10), (2000, 0, 0)).export(tmp_path / "lever.stl")
    return [*files, str(tmp_path / "lever.stl")]


MISTAKES = [
    ([hinge(child="nothing*.stl")], "child pattern 'nothing*.stl' matches no part"),
    ([hinge(parent="*.stl")], "is its parent and child"),
    ([hinge(), hinge(name="h2")], "is moved by two joints ('hinge', 'h2')"),
    (
        [hinge(), hinge(name="lever", parent="[ds]*.stl", child="lever.stl")],
        "matches parts that move differently",
    ),
    (
        [hinge(parent="lever.stl"), hinge(name="back", parent="door.stl", child="lever.stl")],
        "the joints form a cycle (hinge -> back -> hinge)",
    ),
    ([hinge(type="screw")], "unknown type 'screw'"),
    ([hinge(type="continuous")], "a continuous joint takes no range"),
    ([{**hinge(), "range": ["90deg", "10deg"]}], "lower end '90deg' is above its upper end"),
    ([{**hinge(), "range": ["0deg"]}], "range must be two values"),
    ([{**hinge(), "range": ["0", "ninety"]}], "is not a number"),
    ([{**hinge(), "axis": [0, 0, 0]}], "axis must not be zero"),
    ([{**hinge(), "axis": [0, "z", 1]}], "axis must be 3 finite numbers"),
    ([{**hinge(), "origin": [0, 0, 1e300]}], "origin must be 3 finite numbers"),
    ([{**hinge(), "spring": 3}], "unknown key 'spring'"),
    ([{k: v for k, v in hinge().items() if k != "range"}], "a revolute joint needs a range"),
    ([hinge(type="prismatic", origin=[0, 0, 0], range=[0, 1])], "a prismatic joint takes no "),
    ([hinge(name="a=b")], "name must be printable, without ',' or '='"),
    ([hinge(), hinge()], "a joint named 'hinge' comes twice"),
]


@pytest.mark.parametrize(("joints", "message"), MISTAKES, ids=[m for _, m in MISTAKES])
def test_a_mistake_in_the_joint_tables_is_one_line_and_exit_2(tmp_path, joints, message):
    result = run(tmp_path, _two_doors(tmp_path), joints)
    assert result.exit_code == ExitStatus.USAGE, result.output
    lines = [line for line in result.stderr.splitlines() if not line.startswith("meshcheck: ")]
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert "meshcheck.toml" in lines[0] and message in lines[0], lines
    assert "Traceback" not in result.output


def test_degrees_for_a_slide_and_a_pose_of_no_joint_are_usage_errors(tmp_path):
    slide = {k: v for k, v in hinge(type="prismatic", range=[0, "5deg"]).items() if k != "origin"}
    with pytest.raises(ConfigError, match="give its range in report units, not degrees"):
        checked_joints([slide])
    result = run(tmp_path, door_files(tmp_path), [hinge()], "--pose", "elbow=1")
    assert result.exit_code == ExitStatus.USAGE and "no joint named 'elbow'" in result.stderr


@pytest.mark.linux_only
def test_too_many_joint_tables_are_refused_in_a_subprocess(tmp_path):
    """A configuration of MAX_JOINTS + 1 tables is refused before any pattern is matched."""
    box().export(tmp_path / "p.stl")
    chain = [
        {
            "name": f"j{k}",
            "parent": f"p{k}.stl",
            "child": f"p{k + 1}.stl",
            "type": "revolute",
            "axis": [0, 0, 1],
            "range": [-1, 1],
        }
        for k in range(MAX_JOINTS + 1)
    ]
    config = tmp_path / "meshcheck.toml"
    config.write_text(toml(chain))
    code, lines, seconds, peak = measured(
        [tmp_path / "p.stl", "--config", config, "-j", "1"], tmp_path
    )
    assert code == ExitStatus.USAGE and "over the limit of 1000" in lines[-1], lines
    assert seconds < 60 and peak < 1000, (seconds, peak)


def test_a_joint_on_a_moving_part_turns_with_it(tmp_path):
    """A lever hinged at the door's free end (x = 1000): with the door at 90deg and the lever at
    90deg more, the lever's tip (x = 1100 at zero) is at (-100, 1000)."""
    files = door_files(tmp_path)
    box_between((1000, -5, -5), (1100, 5, 5)).export(tmp_path / "lever.stl")
    lever = {"name": "lever", "parent": "door.stl", "child": "lever.stl", "type": "continuous",
             "axis": [0, 0, 1], "origin": [1000, 0, 0]}  # fmt: skip
    motion = Motion(
        pose=parse_pose("hinge=90deg,lever=90deg"), joints=checked_joints([lever, hinge()])
    )
    bodies = load_bodies([*files, str(tmp_path / "lever.stl")], motion=motion)
    lower, upper = bodies[3].world.bounds
    np.testing.assert_allclose(lower[:2], [-100, 995], atol=1e-9)
    np.testing.assert_allclose(upper[:2], [0, 1005], atol=1e-9)


def test_sweep_joints_names_a_joint_table_and_refuses_an_unknown_one(tmp_path):
    files = door_files(tmp_path)
    lever = {"name": "lever", "parent": "stop.stl", "child": "lever.stl", "type": "revolute",
             "axis": [0, 0, 1], "origin": [2000, 0, 0], "range": [0, 1]}  # fmt: skip
    box((10, 10, 10), (2100, 0, 0)).export(tmp_path / "lever.stl")
    files.append(str(tmp_path / "lever.stl"))
    only = run(tmp_path, files, [hinge(), lever], "--sweep-joints", "hinge", "--format", "json")
    assert only.exit_code == ExitStatus.FAILED, only.output  # the door hits its stop
    (robot,) = json.loads(only.stdout)["sweeps"]
    assert {tuple(p["joints"]) for p in robot["pairs"]} == {("hinge",)}  # lever held at 0
    unknown = run(tmp_path, files, [hinge(), lever], "--sweep-joints", "elbow")
    assert unknown.exit_code == ExitStatus.USAGE and "no joint named 'elbow'" in unknown.stderr


def test_parts_no_joint_moves_cost_little_of_the_budget_so_the_door_is_still_swept(tmp_path):
    """Sixty bolts beside a door that hits its stop: 1,953 pairs, of which those the hinge does
    not move are passed over at 64 each (a swept pair costs at least 4,096). A budget of a
    million reaches every pair, the door's collision fails the run; were each passed-over pair
    charged 4,096, 1,708 pairs would be left unswept, and a door later in the order with them."""
    files = door_files(tmp_path)
    for k in range(60):
        x = 3000.0 + 50.0 * k
        box_between((x, 0, 0), (x + 10, 10, 10)).export(tmp_path / f"bolt{k:02d}.stl")
        files.append(str(tmp_path / f"bolt{k:02d}.stl"))
    args = ["--sweep", "--sweep-budget", "1000000", "--format", "json"]
    done = run(tmp_path, files, [hinge()], *args)
    assert done.exit_code == ExitStatus.FAILED, done.output
    (robot,) = json.loads(done.stdout)["sweeps"]
    assert robot["unswept"] == 0 and robot["work"] <= 1_000_000
    pairs = {(p["a"].rsplit("/", 1)[-1], p["b"].rsplit("/", 1)[-1]): p for p in robot["pairs"]}
    assert pairs["door.stl", "stop.stl"]["status"] == "sometimes"
    assert sum(p["status"] == "never" for p in robot["pairs"]) >= 60  # the door and each bolt


def test_a_pose_of_a_robot_and_a_joint_table_together_is_swept(tmp_path):
    """Each mechanism of the run takes the pose values of its own joints: the URDF's joint is
    no joint of the [[joint]] tables' mechanism, nor theirs of the robot's."""
    files = door_files(tmp_path)
    urdf = tmp_path / "door.urdf"
    urdf.write_text(door(1.0).replace('joint name="hinge"', 'joint name="arm_hinge"'))
    pose = ["--pose", "hinge=10deg,arm_hinge=0.1", "--format", "json"]
    result = run(tmp_path, [*files, str(urdf)], [hinge()], *pose, "--sweep")
    assert result.exit_code == ExitStatus.FAILED, result.stderr  # the door meets its stop
    doc = json.loads(result.stdout)
    assert doc["summary"]["pose"] == {
        str(urdf): {"arm_hinge": 0.1},
        str(tmp_path / "meshcheck.toml"): {"hinge": pytest.approx(math.radians(10))},
    }
