"""URDF robots: kinematics with known answers, poses, adjacent links, package://
resolution, bad files refused in one line, and the moveit_resources robots against python-fcl.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner
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


def test_parts_are_named_by_link_and_collision_index(tmp_path):
    second = (
        '<collision><origin xyz="0 0 3"/><geometry><sphere radius="0.5"/></geometry></collision>'
    )
    path = write(tmp_path, slide_robot(arm_extra=second))
    bodies = load_bodies([path])
    assert [b.name for b in bodies] == [f"{path}#{n}" for n in ("arm", "arm/1", "base", "tip")]
    assert all(b.units == "m" for b in bodies)
    sphere = bodies[1].world
    assert np.allclose(sphere.bounds.mean(axis=0), [2, 0, 3], atol=1e-9)


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
