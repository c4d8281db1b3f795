"""URDF robots: kinematics with known answers, poses, adjacent links, package://
resolution, bad files refused in one line, and the moveit_resources robots against python-fcl.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import box, winding_inside

from meshcheck.cli import main
from meshcheck.errors import ConfigError, ExitStatus, InputError
from meshcheck.load import Limits, load_bodies
from meshcheck.load.robot import joint_values, link_transforms, rpy_matrix
from meshcheck.load.urdf import parse_robot
from meshcheck.motion import Motion, parse_pose
from meshcheck.pipeline import check_bodies
from meshcheck.results import Verdict

ROBOTS = os.path.join(os.path.dirname(__file__), "data", "robots")
PANDA = os.path.join(ROBOTS, "panda_description", "urdf", "panda.urdf")
FANUC = os.path.join(ROBOTS, "fanuc_description", "urdf", "fanuc.urdf")
PR2 = os.path.join(ROBOTS, "pr2_description", "urdf", "pr2.urdf")


def slide_robot(*, joint="prismatic", limits='lower="-2" upper="2"', extra="", arm_extra="") -> str:
    """A unit-cube base at the origin and a unit-cube arm 2 m along x on a joint along x (gap 1).

    A third link, a unit cube 'tip', sits fixed 2 m beyond the arm (gap 1), so arm-tip and
    base-arm are adjacent while base-tip are not.
    """
    return f"""<?xml version="1.0"?>
<robot name="slide">
  <link name="base"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <link name="arm">
    <collision><geometry><box size="1 1 1"/></geometry></collision>{arm_extra}
  </link>
  <link name="tip"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <joint name="j" type="{joint}">
    <origin xyz="2 0 0"/><parent link="base"/><child link="arm"/>
    <axis xyz="1 0 0"/><limit {limits}/>
  </joint>
  <joint name="fix" type="fixed">
    <origin xyz="2 0 0"/><parent link="arm"/><child link="tip"/>
  </joint>{extra}
</robot>
"""


def write(tmp_path, text: str, name: str = "robot.urdf") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def statuses(result) -> dict[tuple[str, str], tuple[Verdict, str | None]]:
    return {
        (f.a.rpartition("#")[2], f.b.rpartition("#")[2]): (f.status, f.approval_reason)
        for f in result.findings
    }


def run_cli(*args):
    result = CliRunner().invoke(main, [*map(str, args), "--no-cache", "--no-config", "-j", "1"])
    assert "Traceback" not in (result.stderr or "")
    return result


# ------------------------------------------------------------------------------------------
# Kinematics with known answers


def test_rpy_is_fixed_axis_roll_pitch_yaw():
    """URDF's rpy: roll about x, then pitch about y, then yaw about z, all fixed axes."""
    r = rpy_matrix(0.0, 0.0, math.pi / 2)
    assert np.allclose(r @ [1, 0, 0], [0, 1, 0])
    r = rpy_matrix(math.pi / 2, 0.0, math.pi / 2)  # x->x then yaw: x->y; y->z (roll) stays z
    assert np.allclose(r @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(r @ [0, 1, 0], [0, 0, 1])


def test_revolute_chain_places_links_by_origin_then_motion(tmp_path):
    text = slide_robot(joint="revolute", limits='lower="-3.2" upper="3.2"').replace(
        '<axis xyz="1 0 0"/>', '<axis xyz="0 0 1"/>'
    )
    robot = parse_robot("r.urdf", text.encode())
    links = link_transforms(robot, joint_values(robot, parse_pose("j=90deg")))
    assert np.allclose(links["arm"][:3, 3], [2, 0, 0])
    # the tip is 2 m along the arm's x, which now points along world y
    assert np.allclose(links["tip"][:3, 3], [2, 2, 0])


def test_a_link_of_several_elements_is_one_part_named_by_the_link(tmp_path):
    second = (
        '<collision name="ball"><origin xyz="0 0 3"/><geometry><sphere radius="0.5"/></geometry>'
        "</collision>"
    )
    path = write(tmp_path, slide_robot(arm_extra=second))
    bodies = load_bodies([path])
    assert [b.name for b in bodies] == [f"{path}#{n}" for n in ("arm", "base", "tip")]
    assert all(b.units == "m" for b in bodies)
    arm = bodies[0]
    assert arm.is_closed
    assert [(e.element.index, e.element.name) for e in arm.elements] == [(0, None), (1, "ball")]
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    assert arm.world.volume == pytest.approx(1.0 + sphere.volume, rel=1e-9)  # disjoint: a sum
    assert np.allclose(arm.world.bounds, [[1.5, -0.5, -0.5], [2.5, 0.5, 3.5]], atol=1e-9)
    assert bodies[1].elements == () and bodies[2].elements == ()  # one element: nothing to name


def plate_and_post(*, sunk: float = 0.01, arm_at: str = "0.6 0 0.1") -> str:
    """A base link made of a plate (1 x 1 x 0.1, top at z = 0.1) and a post (0.1 x 0.1 x 0.5)
    sunk ``sunk`` into it, and an arm (a 0.2 cube, 0.1 above its joint) sliding towards the
    post along -x from ``arm_at``."""
    return f"""<robot name="post">
  <link name="base">
    <collision><origin xyz="0 0 0.05"/><geometry><box size="1 1 0.1"/></geometry></collision>
    <collision name="post"><origin xyz="0 0 {0.35 - sunk!r}"/>
      <geometry><box size="0.1 0.1 0.5"/></geometry></collision>
  </link>
  <link name="arm">
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="slide" type="prismatic"><origin xyz="{arm_at}"/><parent link="base"/>
    <child link="arm"/><axis xyz="-1 0 0"/><limit lower="0" upper="0.6"/></joint>
</robot>"""


def test_a_post_sunk_into_its_plate_on_one_link_is_not_a_finding(tmp_path):
    path = write(tmp_path, plate_and_post())
    run = run_cli(path, "--format", "json")
    assert run.exit_code == 0, run.output
    assert "warning" not in run.stderr
    doc = json.loads(run.stdout)
    assert [p["name"] for p in doc["parts"]] == [f"{path}#arm", f"{path}#base"]
    (finding,) = doc["results"]  # the arm resting on the plate, adjacent: no part with itself
    assert finding["approved"] == "adjacent" and finding["a"] != finding["b"]
    (base,) = [b for b in load_bodies([path]) if b.name.endswith("#base")]
    # the union: the plate, and the post's 0.49 above it, counted once
    assert base.is_closed and base.world.volume == pytest.approx(0.1 + 0.01 * 0.49, rel=1e-9)


def test_a_finding_names_the_link_and_the_elements_it_involves(tmp_path):
    """The arm slid onto the post: one interference between the links, its volume the union's
    (counted once), its elements the post (interfering) and the plate (the arm rests on it)."""
    path = write(tmp_path, plate_and_post())
    run = run_cli(path, "--pose", "slide=0.5", "--no-adjacent", "--format", "json")
    assert run.exit_code == ExitStatus.FAILED, run.output
    (finding,) = json.loads(run.stdout)["results"]
    assert (finding["a"], finding["b"]) == (f"{path}#arm", f"{path}#base")
    # decided at its placement rounded to 1/1024 of its tolerance (verify.classes): ~1e-8
    assert finding["volume"] == pytest.approx(0.05 * 0.1 * 0.2, rel=1e-6)
    assert finding["elements"] == [
        {"link": "base", "index": 0, "name": None},
        {"link": "base", "index": 1, "name": "post"},
    ]
    text = run_cli(path, "--pose", "slide=0.5", "--no-adjacent").stdout
    assert "collision elements: base/0, base/1 (post)" in " ".join(text.split())
    html = run_cli(path, "--pose", "slide=0.5", "--no-adjacent", "--format", "html").stdout
    data = json.loads(html.split('id="meshcheck-data">')[1].split("</script>")[0])
    assert data["findings"][0]["elements"] == "base/0, base/1 (post)"
    # lifted clear of the plate, only the post is involved
    path = write(tmp_path, plate_and_post(arm_at="0.6 0 0.15"), "lifted.urdf")
    run = run_cli(path, "--pose", "slide=0.5", "--no-adjacent", "--format", "json")
    (finding,) = json.loads(run.stdout)["results"]
    assert finding["elements"] == [{"link": "base", "index": 1, "name": "post"}]


def box_xml(lower, upper, name=None) -> str:
    centre = " ".join(repr(float(lo + hi) / 2) for lo, hi in zip(lower, upper, strict=True))
    size = " ".join(repr(float(hi - lo)) for lo, hi in zip(lower, upper, strict=True))
    label = f' name="{name}"' if name else ""
    return (
        f'<collision{label}><origin xyz="{centre}"/><geometry><box size="{size}"/></geometry>'
        "</collision>"
    )


def union_overlap(boxes, other) -> float:
    """Volume of (union of ``boxes``) meeting ``other``, all axis-aligned (lower, upper):
    inclusion-exclusion over the boxes, each intersection a box (an exact oracle)."""
    total = 0.0
    for r in range(1, len(boxes) + 1):
        for chosen in itertools.combinations(boxes, r):
            lo = np.max([other[0], *(c[0] for c in chosen)], axis=0)
            hi = np.min([other[1], *(c[1] for c in chosen)], axis=0)
            total += (-1) ** (r + 1) * float(np.prod(np.clip(hi - lo, 0.0, None)))
    return total


corners = st.tuples(*[st.integers(0, 8)] * 3).map(lambda t: np.array(t, dtype=float) / 8.0)


@st.composite
def element_boxes(draw):
    out = []
    for _ in range(draw(st.integers(2, 3))):
        lo = draw(corners)
        size = np.array(draw(st.tuples(*[st.integers(1, 6)] * 3)), dtype=float) / 8.0
        out.append((lo, lo + size))
    return out


@settings(max_examples=12, derandomize=True, deadline=None)
@given(boxes=element_boxes(), at=corners)
def test_interference_with_a_link_of_several_elements_is_the_unions(boxes, at):
    """A link of 2-3 overlapping boxes against a box link: interference exactly when the union
    and the box share volume, of the union's volume (inclusion-exclusion), its elements the
    boxes that meet the other one."""
    other = (at + 0.1, at + 0.6)
    robot = f"""<robot name="r">
  <link name="a">{"".join(box_xml(lo, hi) for lo, hi in boxes)}</link>
  <link name="b">{box_xml(*other)}</link>
  <joint name="fix" type="fixed"><parent link="a"/><child link="b"/></joint>
</robot>"""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "r.urdf")
        with open(path, "w") as fh:
            fh.write(robot)
        bodies = load_bodies([path])
    result = check_bodies(bodies, jobs=1)
    expected = union_overlap(boxes, other)
    volumes = [union_overlap([box], other) for box in boxes]
    if expected < 1e-9:
        assert all(f.status != Verdict.INTERFERENCE for f in result.findings)
        return
    (finding,) = result.findings
    assert finding.status == Verdict.INTERFERENCE
    # decided at its placement rounded to 1/1024 of its tolerance (verify.classes): a face of
    # the unit boxes moves by a few 1e-9 at most
    assert finding.volume == pytest.approx(expected, rel=1e-6, abs=1e-8)
    involved = {e.index for e in finding.elements}
    assert {k for k, v in enumerate(volumes) if v > 1e-9} <= involved


def test_a_mirroring_scale_keeps_an_element_outward(tmp_path):
    """A mesh element mirrored by its scale (-1 1 1) beside a box: the union stays a closed
    outward solid of the two volumes."""
    wedge = trimesh.creation.box(extents=[1, 1, 1])
    wedge.vertices[wedge.vertices[:, 0] > 0, 2] *= 0.5  # a shape a mirror changes
    wedge.export(tmp_path / "wedge.stl")
    robot = f"""<robot name="m"><link name="a">
  <collision><geometry><mesh filename="wedge.stl" scale="-1 1 1"/></geometry></collision>
  {box_xml((2.0, 0.0, 0.0), (3.0, 1.0, 1.0))}
</link></robot>"""
    (body,) = load_bodies([write(tmp_path, robot)])
    assert body.is_closed
    assert body.world.volume == pytest.approx(abs(wedge.volume) + 1.0, rel=1e-9)


def test_a_slide_into_its_neighbour_is_interference_approved_as_adjacent(tmp_path):
    path = write(tmp_path, slide_robot())
    run = run_cli(path, "--pose", "j=-1.5")
    assert run.exit_code == 0, run.output
    assert "adjacent" in run.output and "interference" in run.output
    run = run_cli(path, "--pose", "j=-1.5", "--no-adjacent")
    assert run.exit_code == ExitStatus.FAILED


def test_non_adjacent_links_are_not_approved(tmp_path):
    """base and tip are two joints apart: their clash fails the run."""
    text = slide_robot(limits='lower="-4" upper="2"').replace(
        '<origin xyz="2 0 0"/><parent link="arm"/>', '<origin xyz="0.5 0 0"/><parent link="arm"/>'
    )
    path = write(tmp_path, text)
    run = run_cli(path, "--pose", "j=-2.2")
    assert run.exit_code == ExitStatus.FAILED
    assert "base" in run.output and "tip" in run.output


def test_links_without_geometry_are_passed_through_for_adjacency(tmp_path):
    """MoveIt: a geometry-less link between two links makes them adjacent."""
    from meshcheck.load.robot import adjacent_links

    text = slide_robot().replace(
        '<link name="arm">\n    <collision><geometry><box size="1 1 1"/></geometry></collision>',
        '<link name="arm">',
    )
    robot = parse_robot("r.urdf", text.encode())
    assert adjacent_links(robot) == {frozenset(("base", "tip"))}


def test_mimic_joint_follows_its_leader(tmp_path):
    extra = """
  <link name="twin"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <joint name="m" type="prismatic">
    <origin xyz="0 5 0"/><parent link="base"/><child link="twin"/>
    <axis xyz="0 1 0"/><limit lower="-9" upper="9"/><mimic joint="j" multiplier="2" offset="1"/>
  </joint>"""
    robot = parse_robot("r.urdf", slide_robot(extra=extra).encode())
    values = joint_values(robot, parse_pose("j=0.5"))
    assert values["m"] == pytest.approx(2.0)
    links = link_transforms(robot, values)
    assert np.allclose(links["twin"][:3, 3], [0, 7, 0])
    with pytest.raises(ConfigError, match="mimics 'j'"):
        joint_values(robot, parse_pose("m=0.1"))


# ------------------------------------------------------------------------------------------
# Poses


@pytest.mark.parametrize(
    ("pose", "message"),
    [
        ("j=2.5", "joint 'j': value 2.5 m is beyond its limits [-2, 2] m"),
        ("j=10deg", "joint 'j': is prismatic: give metres, not degrees"),
        ("nope=1", "no joint named 'nope'"),
        ("j=abc", "is not a number"),
        ("j=nan", "is not a number"),
        ("j", "is not JOINT=VALUE"),
        ("j=1,j=2", "more than once"),
        ("fix=0", "is fixed; it takes no value"),
    ],
)
def test_bad_poses_are_usage_errors_naming_the_joint(tmp_path, pose, message):
    run = run_cli(write(tmp_path, slide_robot()), "--pose", pose)
    assert run.exit_code == ExitStatus.USAGE, run.output
    (line,) = run.stderr.strip().splitlines()[-1:]
    assert line.startswith("error: ") and message in line


def test_degrees_and_limits_on_a_revolute_joint(tmp_path):
    robot = parse_robot(PANDA, open(PANDA, "rb").read())
    values = joint_values(robot, parse_pose("panda_joint1=170deg,panda_joint4=-90deg"))
    assert values["panda_joint1"] == pytest.approx(2.9671, abs=1e-4)  # 170deg is the limit
    assert values["panda_joint4"] == pytest.approx(-math.pi / 2)
    assert values["panda_joint2"] == 0.0


def test_pose_from_the_config_table_and_the_option_wins(tmp_path):
    path = write(tmp_path, slide_robot())
    config = tmp_path / "meshcheck.toml"
    config.write_text('adjacent = false\n[pose]\nj = "-1.5"\n')
    run = CliRunner().invoke(main, [path, "--config", str(config), "--no-cache", "-j", "1"])
    assert run.exit_code == ExitStatus.FAILED, run.output  # the slide clashes, not approved
    run = CliRunner().invoke(
        main, [path, "--config", str(config), "--pose", "j=0", "--no-cache", "-j", "1"]
    )
    assert run.exit_code == 0, run.output
    config.write_text("[pose]\nj = true\n")
    run = CliRunner().invoke(main, [path, "--config", str(config), "--no-cache", "-j", "1"])
    assert run.exit_code == ExitStatus.USAGE and "must be a number" in run.stderr


# ------------------------------------------------------------------------------------------
# package:// and meshes


def mesh_robot(filename: str, scale: str = "1 1 1") -> str:
    return f"""<robot name="m">
  <link name="base"><collision><geometry><mesh filename="{filename}" scale="{scale}"/></geometry>
  </collision></link>
</robot>"""


def test_package_urls_resolve_by_package_xml_in_an_ancestor(tmp_path):
    pkg = tmp_path / "src" / "my_description"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "package.xml").write_text("<package><name>my_robot_description</name></package>")
    box((1, 2, 3)).export(pkg / "meshes" / "b.stl")
    urdf = write(pkg / "urdf", mesh_robot("package://my_robot_description/meshes/b.stl", "2 1 1"))
    (body,) = load_bodies([urdf])
    assert np.allclose(body.world.extents, [2, 2, 3])


def test_package_path_option_finds_packages_elsewhere(tmp_path):
    elsewhere = tmp_path / "ws" / "pkg_a"
    (elsewhere / "meshes").mkdir(parents=True)
    (elsewhere / "package.xml").write_text("<package><name>pkg_a</name></package>")
    box().export(elsewhere / "meshes" / "b.obj")
    urdf = write(tmp_path, mesh_robot("package://pkg_a/meshes/b.obj"), "r.urdf")
    with pytest.raises(InputError, match="not found in package 'pkg_a'"):
        load_bodies([urdf])
    bodies = load_bodies([urdf], motion=Motion(package_paths=(str(tmp_path / "ws"),)))
    assert len(bodies) == 1
    run = run_cli(urdf, "--package-path", tmp_path / "ws")
    assert run.exit_code == 0, run.output


def test_a_mesh_shared_by_links_is_read_once(tmp_path):
    box().export(tmp_path / "b.stl")
    text = slide_robot()
    for link in ("base", "arm", "tip"):
        text = text.replace(
            f'<link name="{link}"><collision><geometry><box size="1 1 1"/>',
            f'<link name="{link}"><collision><geometry><mesh filename="b.stl"/>',
        )
    text = text.replace('<box size="1 1 1"/>', '<mesh filename="b.stl"/>')
    bodies = load_bodies([write(tmp_path, text)])
    assert len({id(b.mesh) for b in bodies}) == 1 and len(bodies) == 3


# ------------------------------------------------------------------------------------------
# Robot options without a robot: one line, exit 2, before any work


@pytest.mark.parametrize(
    "option",
    [
        ["--pose", "j=1"],
        ["--sweep"],
        ["--sweep-joints", "j"],
        ["--srdf", "OUT"],
        ["--audit-srdf", "SRDF"],
    ],
    ids=lambda o: o[0],
)
def test_robot_options_without_a_robot_are_refused_before_any_work(tmp_path, option):
    """The input is no mesh at all (read, it would be exit 3): exit 2 shows nothing was read;
    no output is written."""
    junk = tmp_path / "part.stl"
    junk.write_bytes(b"not a mesh")
    srdf = tmp_path / "robot.srdf"
    srdf.write_text('<robot name="r"/>')
    args = [str(tmp_path / "out.srdf") if a == "OUT" else str(srdf) if a == "SRDF" else a
            for a in option]  # fmt: skip
    run = run_cli(junk, *args)
    assert run.exit_code == ExitStatus.USAGE, run.output
    (line,) = run.stderr.strip().splitlines()
    assert line.startswith(f"error: {option[0]}: ")
    assert "URDF robot" in line and not (tmp_path / "out.srdf").exists()


def test_an_srdf_of_two_robots_is_refused_before_any_work(tmp_path):
    a, b = write(tmp_path, slide_robot(), "a.urdf"), write(tmp_path, slide_robot(), "b.urdf")
    run = run_cli(a, b, "--srdf", tmp_path / "out.srdf")
    assert run.exit_code == ExitStatus.USAGE
    assert run.stderr.strip().splitlines() == [
        f"error: --srdf: an SRDF describes one URDF robot; the inputs hold 2: {a}, {b}"
    ]


def test_a_pose_for_a_joint_table_or_from_the_configuration_is_not_refused(tmp_path):
    """A [[joint]] mechanism takes --pose; a [pose] table of a shared configuration is left
    alone by runs without a robot."""
    box().export(tmp_path / "a.stl")
    box(at=(3, 0, 0)).export(tmp_path / "b.stl")
    config = tmp_path / "meshcheck.toml"
    config.write_text('[pose]\nelbow = "30deg"\n')
    files = [tmp_path / "a.stl", tmp_path / "b.stl"]
    run = CliRunner().invoke(main, [*map(str, files), "--config", str(config), "--no-cache"])
    assert run.exit_code == 0, run.output
    config.write_text(
        '[[joint]]\nname = "hinge"\nparent = "a.stl"\nchild = "b.stl"\ntype = "revolute"\n'
        "axis = [0, 0, 1]\nrange = [-1, 1]\n"
    )
    args = [*map(str, files), "--config", str(config), "--no-cache", "--pose", "hinge=0.5"]
    run = CliRunner().invoke(main, args)
    assert run.exit_code == 0, run.output


# ------------------------------------------------------------------------------------------
# The pose every report records


def test_every_format_records_the_pose(tmp_path):
    """Given values as given (degrees in radians), the others at 0 or at the limit nearest 0
    (the slide's range here starts at 0.25)."""
    from meshcheck.pipeline import check
    from meshcheck.reports import render

    path = write(tmp_path, slide_robot(limits='lower="0.25" upper="2"'))
    result = check([path], config=None, cache_dir=None, jobs=1, motion={"pose": "j=0.5"})
    (pose,) = result.poses
    assert pose.joints == (("j", 0.5),)
    result = check([path], config=None, cache_dir=None, jobs=1)
    assert result.poses[0].joints == (("j", 0.25),)
    doc = json.loads(render(result, "json"))
    assert doc["summary"]["pose"] == {path: {"j": 0.25}}
    assert "pose robot.urdf: j=0.25\n" in render(result, "text")
    from meshcheck.reports.markdown import escape

    assert f"Pose of {escape(path)}: {escape('j=0.25')}\n" in render(result, "markdown")
    assert f"meshcheck: pose {path}: j=0.25\n" in render(result, "github")
    assert f'<property name="pose" value="{path}: j=0.25" />' in render(result, "junit")
    sarif = json.loads(render(result, "sarif"))
    assert sarif["runs"][0]["properties"]["pose"] == {path: {"j": 0.25}}
    html = render(result, "html")
    data = json.loads(html.split('id="meshcheck-data">')[1].split("</script>")[0])
    assert data["poses"] == [{"robot": path, "text": "j=0.25"}]
    assert data["summary"]["pose"] == {path: {"j": 0.25}}


def test_the_pose_of_a_robot_at_zero_and_of_a_run_without_robots(tmp_path):
    from meshcheck.pipeline import check
    from meshcheck.reports import render

    path = write(tmp_path, slide_robot())
    result = check([path], config=None, cache_dir=None, jobs=1)
    assert "pose robot.urdf: every joint at 0\n" in render(result, "text")
    box().export(tmp_path / "a.stl")
    box(at=(3, 0, 0)).export(tmp_path / "b.stl")
    stls = [str(tmp_path / "a.stl"), str(tmp_path / "b.stl")]
    result = check(stls, config=None, cache_dir=None, jobs=1)
    assert result.poses == () and json.loads(render(result, "json"))["summary"]["pose"] is None
    assert "pose" not in render(result, "text")


def test_a_mechanism_of_joint_tables_records_its_pose(tmp_path):
    box().export(tmp_path / "a.stl")
    box(at=(3, 0, 0)).export(tmp_path / "b.stl")
    config = tmp_path / "meshcheck.toml"
    config.write_text(
        '[[joint]]\nname = "hinge"\nparent = "a.stl"\nchild = "b.stl"\ntype = "revolute"\n'
        "axis = [0, 0, 1]\nrange = [-1, 1]\n"
    )
    files = [str(tmp_path / "a.stl"), str(tmp_path / "b.stl")]
    args = [*files, "--config", str(config), "--no-cache", "--pose", "hinge=30deg"]
    run = CliRunner().invoke(main, [*args, "--format", "json"])
    assert json.loads(run.stdout)["summary"]["pose"] == {str(config): {"hinge": math.radians(30)}}


# ------------------------------------------------------------------------------------------
# Files a URDF names are read inside its folders only


def outside_layout(tmp_path) -> dict[str, str]:
    """A workspace ``ws/src/pkg`` (package.xml naming ``pkg``) holding a URDF in ``urdf/`` and
    a mesh in ``meshes/``, and a secret mesh outside it, in ``secret/``."""
    pkg = tmp_path / "ws" / "src" / "pkg"
    (pkg / "urdf").mkdir(parents=True)
    (pkg / "meshes").mkdir()
    (pkg / "package.xml").write_text("<package><name>pkg</name></package>")
    box().export(pkg / "meshes" / "b.stl")
    (tmp_path / "secret").mkdir()
    box().export(tmp_path / "secret" / "key.stl")
    return {"pkg": str(pkg), "secret": str(tmp_path / "secret" / "key.stl")}


@pytest.mark.parametrize(
    ("filename", "allowed"),
    [
        ("package://pkg/meshes/b.stl", True),
        ("../meshes/b.stl", True),  # inside the package the URDF lies in
        ("PKG/meshes/b.stl", True),  # an absolute path inside it
        ("file://PKG/meshes/b.stl", True),
        ("package://pkg/../../../secret/key.stl", False),
        ("../../../../secret/key.stl", False),
        ("SECRET", False),
        ("file://SECRET", False),
    ],
)
def test_mesh_files_outside_the_robots_folders_are_refused(tmp_path, filename, allowed):
    from meshcheck.load.urdf import resolve_mesh

    where = outside_layout(tmp_path)
    filename = filename.replace("PKG", where["pkg"]).replace("SECRET", where["secret"])
    urdf = os.path.join(where["pkg"], "urdf", "r.urdf")
    if allowed:
        assert os.path.samefile(resolve_mesh(urdf, filename), os.path.join(where["pkg"],
                                "meshes", "b.stl"))  # fmt: skip
    else:
        with pytest.raises(InputError, match="refused") as info:
            resolve_mesh(urdf, filename)
        assert info.value.path == urdf and "\n" not in str(info.value)
        assert os.path.samefile(resolve_mesh(urdf, filename, allow_outside=True), where["secret"])


def test_a_folder_above_named_like_a_package_is_no_package(tmp_path):
    """``package://home/...`` from a URDF below /home would be /home: a package is a folder
    whose package.xml names it (or one --package-path gives)."""
    from meshcheck.load.urdf import package_roots

    (tmp_path / "home" / "robot").mkdir(parents=True)
    box().export(tmp_path / "home" / "key.stl")
    urdf = write(tmp_path / "home" / "robot", mesh_robot("package://home/key.stl"))
    assert package_roots(urdf, "home") == []
    with pytest.raises(InputError, match="not found in package 'home'"):
        load_bodies([urdf])
    assert package_roots(urdf, "home", [str(tmp_path)]) == [str(tmp_path / "home")]


def test_configuration_package_paths_stay_inside_its_folder(tmp_path):
    path = write(tmp_path, slide_robot())
    config = tmp_path / "meshcheck.toml"
    for outside in ('"/"', '"../.."', '["sub", "../x"]'):
        config.write_text(f"package_paths = {outside}\n")
        run = CliRunner().invoke(main, [path, "--config", str(config), "--no-cache"])
        assert run.exit_code == ExitStatus.USAGE, run.output
        assert "outside the configuration's folder" in run.stderr.strip().splitlines()[-1]
    config.write_text('package_paths = ["sub"]\n')
    run = CliRunner().invoke(main, [path, "--config", str(config), "--no-cache"])
    assert run.exit_code == 0, run.output


# ------------------------------------------------------------------------------------------
# Bad URDF: one line, exit 3


def joint_xml(name, parent, child, kind="fixed"):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        '<limit lower="0" upper="1"/></joint>'
    )


def link_xml(name):
    box_xml = '<geometry><box size="1 1 1"/></geometry>'
    return f'<link name="{name}"><collision>{box_xml}</collision></link>'


BAD = {
    "cycle": link_xml("a") + link_xml("b") + link_xml("c") + joint_xml("ab", "a", "b")
    + joint_xml("bc", "b", "c") + joint_xml("cb", "c", "b"),
    "loop without root": link_xml("a") + link_xml("b") + joint_xml("ab", "a", "b")
    + joint_xml("ba", "b", "a"),
    "missing parent": link_xml("a") + joint_xml("ab", "ghost", "a"),
    "unknown type": link_xml("a") + link_xml("b") + joint_xml("ab", "a", "b", "hinge"),
    "two roots": link_xml("a") + link_xml("b"),
    "missing mesh": '<link name="a"><collision><geometry><mesh filename="nope.stl"/></geometry>'
    "</collision></link>",
    "nan origin": '<link name="a"><collision><origin xyz="0 nan 0"/><geometry><box size="1 1 1"/>'
    "</geometry></collision></link>",
    "short size": '<link name="a"><collision><geometry><box size="1 1"/></geometry></collision>'
    "</link>",
    "no collision": '<link name="a"/>',
    "revolute without limit": link_xml("a") + link_xml("b")
    + '<joint name="ab" type="revolute"><parent link="a"/><child link="b"/></joint>',
}  # fmt: skip
REASONS = {
    "cycle": "two parent joints",
    "loop without root": "cycle",
    "missing parent": "parent link 'ghost' is not defined",
    "unknown type": "unknown type 'hinge'",
    "two roots": "several root links",
    "missing mesh": "nope.stl: no such file",
    "nan origin": "NaN or infinite",
    "short size": "is not 3 numbers",
    "no collision": "no link has collision geometry",
    "revolute without limit": "needs a <limit>",
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_urdf_is_one_line_exit_3(tmp_path, case):
    path = write(tmp_path, f'<robot name="bad">{BAD[case]}</robot>')
    run = run_cli(path)
    assert run.exit_code == ExitStatus.INPUT, run.output
    lines = run.stderr.strip().splitlines()
    assert lines[-1].startswith(f"error: {path}: ") and REASONS[case] in lines[-1]


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("<robot><link", "not well-formed XML"),
        ("<model/>", "not <robot>"),
        ('<!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="&a;"/>', "document type"),
        ('<!DOCTYPE r SYSTEM "file:///etc/passwd"><robot/>', "document type"),
        ('<robot xmlns:xacro="x"><xacro:macro name="m"/></robot>', "xacro"),
        ("<robot>" + "<a>" * 100 + "</a>" * 100 + "</robot>", "levels deep"),
        ("<robot>" + "<link/>" * 200_001 + "</robot>", "more than 200000 elements"),
    ],
)
def test_hostile_or_foreign_xml_is_refused(tmp_path, text, reason):
    with pytest.raises(InputError, match=reason):
        load_bodies([write(tmp_path, text)])


def test_a_urdf_over_the_file_limit_is_refused_before_parsing(tmp_path):
    path = write(tmp_path, slide_robot())
    with pytest.raises(InputError, match="over the limit"):
        load_bodies([path], limits=Limits(max_file_bytes=100))


def test_billion_laughs_is_refused_quickly_in_little_memory(tmp_path):
    """The entity bomb stdlib ElementTree would expand to gigabytes: refused at its DOCTYPE."""
    entities = ['<!ENTITY l0 "lol">'] + [
        f'<!ENTITY l{k} "{("&l" + str(k - 1) + ";") * 10}">' for k in range(1, 10)
    ]
    text = f'<!DOCTYPE robot [{"".join(entities)}]><robot name="&l9;"/>'
    path = write(tmp_path, text)
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "meshcheck", path, "--no-cache", "--no-config"],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert proc.returncode == ExitStatus.INPUT
    assert proc.stderr.strip().splitlines()[-1].endswith("(refused: entity expansion)")
    assert time.perf_counter() - start < 60


# ------------------------------------------------------------------------------------------
# The moveit_resources robots against python-fcl


def contains_vertex(outer, inner) -> bool:
    """Whether a vertex of ``inner`` lies inside closed ``outer`` (a part buried in another,
    which FCL's surface test does not see)."""
    return bool(winding_inside(outer, inner.vertices[:50]).any())


def random_pose(path: str, seed: int) -> str:
    robot = parse_robot(path, open(path, "rb").read())
    rng = np.random.default_rng(seed)
    values = (rng.uniform(max(j.lower, -math.pi), min(j.upper, math.pi)) for j in robot.movable)
    return ",".join(f"{j.name}={v:.6f}" for j, v in zip(robot.movable, values, strict=True))


@pytest.mark.parametrize(
    ("robot", "seed"),
    [(r, s) for r in (PANDA, FANUC) for s in (None, 1, 2, 3)] + [(PR2, None)],
    ids=lambda v: os.path.basename(v) if isinstance(v, str) else str(v),
)
@pytest.mark.filterwarnings("ignore::meshcheck.errors.MeshcheckWarning")
def test_findings_agree_with_fcl_on_the_posed_meshes(robot, seed):
    """Interference and touching as FCL sees the posed surfaces (some PR2 meshes are open, or
    hold overlapping shells: warned about, and their findings rest on surfaces, as FCL's do)."""
    from meshes import fcl_collide

    pose = () if seed is None else parse_pose(random_pose(robot, seed))
    bodies = load_bodies([robot], motion=Motion(pose=pose))
    result = check_bodies(bodies)
    found = {tuple(sorted((f.a, f.b))): f.status for f in result.findings}
    colliding = 0
    for i, a in enumerate(bodies):
        for b in bodies[i + 1 :]:
            key = tuple(sorted((a.name, b.name)))
            status = found.get(key)
            if fcl_collide(a.world, b.world):
                colliding += 1
                assert status in (Verdict.INTERFERENCE, Verdict.TOUCHING), key
            elif status == Verdict.INTERFERENCE:  # buried: FCL tests surfaces only
                assert contains_vertex(a.world, b.world) or contains_vertex(b.world, a.world), key
    assert seed is not None or colliding > 0
