"""The sweep: never proven, sometimes with a witness, against closed forms, python-fcl
and random sampling; the motion bound the proof rests on; the SRDF it writes.
"""

from __future__ import annotations

import itertools
import math
import os

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import settings as hypothesis_settings
from hypothesis import strategies as st
from meshes import fcl_collide, fcl_distance, winding_inside

from meshcheck.cli import main
from meshcheck.errors import ExitStatus
from meshcheck.load import load_assembly, load_bodies
from meshcheck.load.robot import joint_values, link_transforms, with_mimics
from meshcheck.load.urdf import parse_robot
from meshcheck.motion import Motion, parse_pose
from meshcheck.settings import Settings
from meshcheck.sweep import sweep_bodies
from meshcheck.sweep.distances import link_geometries
from meshcheck.sweep.kinematics import link_sides, motion_weights
from meshcheck.sweep.search import LinkPair

ROBOTS = os.path.join(os.path.dirname(__file__), "data", "robots")
PANDA = os.path.join(ROBOTS, "panda_description", "urdf", "panda.urdf")
PR2 = os.path.join(ROBOTS, "pr2_description", "urdf", "pr2.urdf")

# A door 1 m long and 0.1 m thick on a hinge about z at the origin, and a stop (a box from
# x 0.5..0.8, y 0.3..0.5) on the frame. Opening (positive angle), the door's face y' = T/2
# first meets the stop's corner (BX, CY): -sin(a) BX + cos(a) CY = T/2, so
# a* = acos(T / 2 / R) - atan2(BX, CY), R = |(BX, CY)|.
T, BX, CY = 0.1, 0.8, 0.3
STOP_ANGLE = math.acos(T / 2 / math.hypot(BX, CY)) - math.atan2(BX, CY)


def door(upper: float, *, stop_at: str = "0.65 0.4 0") -> str:
    return f"""<robot name="door">
  <link name="frame"/>
  <link name="stop"><collision><origin xyz="{stop_at}"/>
    <geometry><box size="0.3 0.2 0.2"/></geometry></collision></link>
  <link name="door"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 {T} 0.2"/></geometry></collision></link>
  <joint name="hinge" type="revolute"><parent link="frame"/><child link="door"/>
    <axis xyz="0 0 1"/><limit lower="-0.5" upper="{upper!r}"/></joint>
  <joint name="fix" type="fixed"><parent link="frame"/><child link="stop"/></joint>
</robot>"""


def sweep(path: str, **motion):
    settings = Settings(motion=Motion(sweep=(), **motion))
    assembly = load_assembly([path], motion=settings.motion)
    (robot,) = sweep_bodies(assembly.bodies, assembly.mechanisms, settings)
    return {(p.a, p.b): p for p in robot.pairs}


def write(tmp_path, text: str, name: str = "robot.urdf") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


# ------------------------------------------------------------------------------------------
# Known answers


@pytest.mark.parametrize("margin", [1e-3, 1e-4])
def test_hinge_stop_angle_is_found_within_the_tolerance(tmp_path, margin):
    """Limits just short of the closed-form stop angle: never (proven); just past it: sometimes,
    with a witness between the stop angle and the limit."""
    short = sweep(write(tmp_path, door(STOP_ANGLE - margin)), resolution=margin / 10)
    assert short["door", "stop"].status == "never"
    past = sweep(write(tmp_path, door(STOP_ANGLE + margin)), resolution=margin / 10)
    pair = past["door", "stop"]
    assert pair.status == "sometimes" and pair.verdict in ("interference", "touching")
    assert STOP_ANGLE - 1e-9 <= pair.witness["hinge"] <= STOP_ANGLE + margin


def test_a_stop_out_of_reach_is_never_and_written_to_the_srdf(tmp_path):
    path = write(tmp_path, door(1.5, stop_at="2 0 0"))
    srdf = tmp_path / "robot.srdf"
    run = CliRunner().invoke(
        main, [path, "--srdf", str(srdf), "--no-adjacent", "--no-cache", "--no-config", "-j", "1"]
    )
    assert run.exit_code == 0, run.output
    assert '<disable_collisions link1="door" link2="stop" reason="Never"/>' in srdf.read_text()
    assert "1 never" in run.stderr


def test_srdf_marks_adjacent_links_and_leaves_colliding_pairs_checked(tmp_path):
    path = write(tmp_path, door(1.5))
    srdf = tmp_path / "robot.srdf"
    args = [path, "--srdf", str(srdf), "--no-cache", "--no-config", "-j", "1"]
    run = CliRunner().invoke(main, args)
    assert run.exit_code == 0, run.output
    assert 'reason="Adjacent"' in srdf.read_text()
    run = CliRunner().invoke(main, [*args, "--no-adjacent"])
    assert run.exit_code == 0, run.output
    assert "disable_collisions" not in srdf.read_text()  # sometimes: MoveIt keeps checking
    assert "1 sometimes" in run.stderr


def test_sweeping_an_unknown_joint_is_a_usage_error(tmp_path):
    path = write(tmp_path, door(1.0))
    run = CliRunner().invoke(
        main, [path, "--sweep-joints", "nope", "--no-cache", "--no-config", "-j", "1"]
    )
    assert run.exit_code == ExitStatus.USAGE
    assert "no joint named 'nope'" in run.stderr


# ------------------------------------------------------------------------------------------
# A narrow window random sampling misses

L, W, GAP = 1.0, 0.02, 0.0005  # arm length, thickness, how far the tips overlap head-on


def two_arms() -> str:
    """Two arms turning about parallel axes 2L - GAP apart: their tips meet only when both
    point at each other within about 2 degrees."""
    arm = f'<origin xyz="{L / 2} 0 0"/><geometry><box size="{L} {W} {W}"/></geometry>'
    return f"""<robot name="arms">
  <link name="base"/>
  <link name="a"><collision>{arm}</collision></link>
  <link name="b"><collision>{arm}</collision></link>
  <joint name="ja" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-3.14159" upper="3.14159"/></joint>
  <joint name="jb" type="revolute"><origin xyz="{2 * L - GAP} 0 0"/><parent link="base"/>
    <child link="b"/><axis xyz="0 0 1"/><limit lower="-3.14159" upper="3.14159"/></joint>
</robot>"""


def test_a_narrow_window_that_10000_random_poses_miss_is_found_with_its_witness(tmp_path):
    path = write(tmp_path, two_arms())
    robot = parse_robot(path, open(path, "rb").read())
    rng = np.random.default_rng(0)
    samples = rng.uniform(-3.14159, 3.14159, size=(10_000, 2))
    a_local, b_local = (b.mesh for b in load_bodies([path]))
    hits = 0
    for ja, jb in samples:
        links = link_transforms(robot, joint_values(robot, parse_pose(f"ja={ja},jb={jb}")))
        a = a_local.copy().apply_transform(links["a"])
        b = b_local.copy().apply_transform(links["b"])
        hits += fcl_collide(a, b)
    assert hits == 0  # MoveIt's 10,000 samples would disable this pair as "Never"

    pair = sweep(path)["a", "b"]
    assert pair.status == "sometimes"
    pose = ",".join(f"{k}={v!r}" for k, v in pair.witness.items())
    posed = load_bodies([path], motion=Motion(pose=parse_pose(pose)))
    assert fcl_collide(posed[0].world, posed[1].world)  # the witness, confirmed independently
    assert abs(pair.witness["ja"]) < math.radians(3)
    assert abs(abs(pair.witness["jb"]) - math.pi) < math.radians(3)


# ------------------------------------------------------------------------------------------
# The bound the proof rests on, and agreement on the panda


def test_no_point_moves_farther_than_the_motion_bound():
    """For random boxes of the panda's joints, every vertex of the two links moves (relative to
    the pair's common frame) by at most sum_k w_k |q_k - c_k| between the centre and any pose:
    with the weights from the links' radii, and with the tighter ones from their points'
    distances to the joint axes."""
    assembly = load_assembly([PANDA])
    bodies, (mech,) = assembly.bodies, assembly.mechanisms
    robot = mech.robot
    base = joint_values(robot)
    swept = {j.name for j in robot.movable}
    at_zero = link_transforms(robot, base)
    local = {}
    for link, ks in mech.parts.items():
        inverse = np.linalg.inv(at_zero[link])
        local[link] = np.vstack([bodies[k].world.vertices @ inverse[:3, :3].T + inverse[:3, 3]
                                 for k in ks])  # fmt: skip
    radius = {link: float(np.linalg.norm(v, axis=1).max()) for link, v in local.items()}
    rng = np.random.default_rng(1)
    cases = [("panda_link0", "panda_hand"), ("panda_link2", "panda_leftfinger")]
    for (a, b), points in itertools.product(cases, (None, local)):
        weights = motion_weights(robot, (a, b), radius, swept, base, points=points)
        if points is not None:  # distances from the axes: tighter than radii, never looser
            loose = motion_weights(robot, (a, b), radius, swept, base)
            assert all(weights[n] <= loose[n] + 1e-12 for n in loose)
            if b == "panda_hand":  # turned by joint 7 about an axis through it
                assert sum(weights.values()) < sum(loose.values())
        names = sorted(weights)
        lo = np.array([robot.joint(n).lower for n in names])
        hi = np.array([robot.joint(n).upper for n in names])
        for _ in range(40):
            centre = rng.uniform(lo, hi)
            pose = np.clip(centre + rng.uniform(-0.3, 0.3, len(names)), lo, hi)
            moved = []
            for q in (centre, pose):
                values = dict(base, **dict(zip(names, q, strict=True)))
                links = link_transforms(robot, values)
                # relative to link a: the distance between the links is what matters
                rel = np.linalg.inv(links[a]) @ links[b]
                moved.append(local[b] @ rel[:3, :3].T + rel[:3, 3])
            displacement = np.linalg.norm(moved[1] - moved[0], axis=1).max()
            bound = sum(
                weights[n] * abs(p - c) for n, p, c in zip(names, pose, centre, strict=True)
            )
            assert displacement <= bound + 1e-12


def hull_links(urdf: str, only=None):
    """(robot, bodies, joint values at zero, every movable joint, link geometries) of a URDF
    robot whose parts are each one convex piece, its hull (so the real meshes lie inside);
    the geometries of the links ``only`` (default all)."""
    assembly = load_assembly([urdf])
    bodies, (mech,) = assembly.bodies, assembly.mechanisms
    robot = mech.robot
    base = joint_values(robot)
    swept = {j.name for j in robot.movable}
    pieces = {k: [bodies[k].world.convex_hull.vertices] for ks in mech.parts.values() for k in ks}
    links = link_geometries(robot, mech, bodies, pieces, base, 1.0, only=only)
    return robot, bodies, base, swept, links


@pytest.mark.filterwarnings("ignore::meshcheck.errors.MeshcheckWarning")  # the PR2's open meshes
@pytest.mark.parametrize(
    ("urdf", "pairs"),
    [
        (PANDA, [("panda_link0", "panda_hand"), ("panda_leftfinger", "panda_rightfinger")]),
        (PR2, [("l_forearm_link", "r_gripper_l_finger_tip_link"),
               ("head_tilt_link", "l_wrist_roll_link")]),
    ],
)  # fmt: skip
def test_no_point_moves_farther_than_the_box_bound(urdf, pairs):
    """The bound of a box, lever arms taken at its centre pose (``LinkPair.box_weights``): for
    random boxes, every hull vertex of the two links moves by at most ``sum_k r_k h_k`` in all
    (each link relative to the pair's common frame) between the centre and any pose in the box;
    it is never looser than the bound over the whole sweep, and on the PR2's arms it is
    tighter."""
    robot, bodies, base, swept, links = hull_links(urdf)
    radius = {n: link.radius for n, link in links.items()}
    points = {n: link.points for n, link in links.items()}
    rng = np.random.default_rng(2)
    tighter = 0
    for a, b in pairs:
        weights = motion_weights(robot, (a, b), radius, swept, base, 1.0, points)
        names = sorted(weights)
        sides = link_sides(robot, (a, b), links, names, swept, base, 1.0)
        pair = LinkPair(robot, a, b, names, sides, base, 1.0, 0.0, links, bodies)
        lo = np.array([robot.joint(n).lower for n in names])
        hi = np.array([robot.joint(n).upper for n in names])
        lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
        for _ in range(30):
            half = rng.uniform(0.0, 0.4 if _ % 2 else 0.05, len(names)) * (hi - lo)
            centre = rng.uniform(lo + half, hi - half)
            axes: dict = {}
            ta, tb, _ = pair.placements(centre[None, :], axes)
            w = pair.box_weights(ta, tb, axes, half[None, :])[0]
            bound = float(half @ w)
            loose = float(half @ np.array([weights[n] for n in names]))
            assert bound <= loose * (1 + 1e-12) + 1e-12
            tighter += bound < 0.9 * loose
            poses = centre + half * rng.uniform(-1.0, 1.0, (40, len(names)))
            poses[:8] = centre + half * rng.choice([-1.0, 1.0], (8, len(names)))  # corners
            ua, ub, _ = pair.placements(poses)
            moved = 0.0
            for link, at_centre, at_pose in ((a, ta, ua), (b, tb, ub)):
                local = links[link].points
                p0 = local @ at_centre[0, :3, :3].T + at_centre[0, :3, 3]
                p1 = np.einsum("nj,eij->eni", local, at_pose[:, :3, :3]) + at_pose[:, None, :3, 3]
                moved = moved + np.linalg.norm(p1 - p0, axis=2).max(axis=1)
            assert moved.max() <= bound + 1e-9
    if urdf == PR2:  # most small boxes: lever arms at their centre pose
        assert tighter >= 15


@pytest.mark.filterwarnings("ignore::meshcheck.errors.MeshcheckWarning")  # the PR2's open meshes
def test_surface_distance_agrees_with_fcl():
    """The real meshes' distance a box is certified with when its pieces do not suffice
    (``surface_distance``) is FCL's distance between the posed meshes, at random poses of the
    PR2's forearm and upper arm (a pair whose convex pieces overlap at every pose), and a value
    above ``reach`` when they are farther apart than that."""
    import trimesh

    from meshcheck.sweep.distances import surface_distance

    robot, _, base, _, links = hull_links(PR2)
    a, b = "l_forearm_link", "l_upper_arm_link"
    rng = np.random.default_rng(3)
    for _ in range(6):
        values = dict(base)
        for name in ("l_elbow_flex_joint", "l_forearm_roll_joint"):
            joint = robot.joint(name)
            lo = joint.lower if np.isfinite(joint.lower) else -np.pi
            hi = joint.upper if np.isfinite(joint.upper) else np.pi
            values[name] = rng.uniform(lo, hi)
        placed = link_transforms(robot, values)
        meshes = [trimesh.Trimesh(links[n].vertices, links[n].faces, process=False)
                  .apply_transform(placed[n]) for n in (a, b)]  # fmt: skip
        expected = fcl_distance(*meshes)
        got = surface_distance(links[a], links[b], placed[a], placed[b], 1.0)
        assert got == pytest.approx(expected, abs=1e-9)
        if expected > 1e-4:
            assert surface_distance(links[a], links[b], placed[a], placed[b], expected / 2) > (
                expected / 2
            )


@pytest.mark.filterwarnings("ignore::meshcheck.errors.MeshcheckWarning")  # the PR2's open meshes
@pytest.mark.parametrize(
    "a, b",
    [
        # seven joints
        ("head_tilt_link", "l_forearm_link"),
        # nine: the head tilted to its limit and the arm raised to its, the wrist rolled and
        # flexed into the camera mount; ten descent steps from these starts stop short of it
        ("head_mount_link", "r_wrist_roll_link"),
    ],
)
def test_descent_finds_a_collision_sampling_misses(a, b):
    """Two PR2 links that collide only in a small corner of their joints (python-fcl's 10,000
    samples in bench/sweep.py never hit it): descending the pieces' distance from the nearest
    of a few hundred box centres finds a pose where the real meshes collide, and FCL agrees
    there."""
    import trimesh

    from meshcheck.sweep.kinematics import joint_ranges
    from meshcheck.sweep.search import NearestCentres, descent_witness

    robot, bodies, base, swept, links = hull_links(PR2)
    radius = {n: link.radius for n, link in links.items()}
    points = {n: link.points for n, link in links.items()}
    names = sorted(motion_weights(robot, (a, b), radius, swept, base, 1.0, points))
    sides = link_sides(robot, (a, b), links, names, swept, base, 1.0)
    pair = LinkPair(robot, a, b, names, sides, base, 1.0, 1e-5, links, bodies)
    lower, upper = joint_ranges(robot, names)
    values = lower + (upper - lower) * np.random.default_rng(0).random((512, len(names)))
    ta, tb, _ = pair.placements(values)
    nearest = NearestCentres(8)
    nearest.add(pair.distances(ta, tb, np.full(len(values), 1.0))[0], values)
    found = descent_witness(pair, lower, upper, nearest.values, 512)
    assert found is not None and found.status == "sometimes"
    pose = dict(base, **found.witness)
    placed = link_transforms(robot, with_mimics(robot, pose))
    meshes = [trimesh.Trimesh(links[n].vertices, links[n].faces, process=False)
              .apply_transform(placed[n]) for n in (a, b)]  # fmt: skip
    assert fcl_collide(*meshes) or fcl_distance(*meshes) <= 1e-5


def test_panda_wrist_sweep_agrees_with_fcl_sampling():
    """Sweep the panda's last two joints: no never pair collides at 300 fcl-sampled poses, and
    every sometimes pair's witness collides in fcl (or one link is buried in the other)."""
    settings = Settings(motion=Motion(sweep=("panda_joint6", "panda_joint7")))
    assembly = load_assembly([PANDA])
    bodies, (mech,) = assembly.bodies, assembly.mechanisms
    (robot_sweep,) = sweep_bodies(bodies, [mech], settings)
    by_pair = {(p.a, p.b): p for p in robot_sweep.pairs}
    assert by_pair["panda_hand", "panda_link5"].status == "sometimes"
    assert by_pair["panda_link3", "panda_link7"].status == "never"
    robot = mech.robot
    at_zero = link_transforms(robot, joint_values(robot))
    local = {
        link: bodies[ks[0]]
        .mesh.copy()
        .apply_transform(np.linalg.inv(at_zero[link]) @ bodies[ks[0]].transform)
        for link, ks in mech.parts.items()
    }

    def posed(values: dict) -> dict:
        links = link_transforms(robot, joint_values(robot, parse_pose(values)))
        return {link: mesh.copy().apply_transform(links[link]) for link, mesh in local.items()}

    rng = np.random.default_rng(2)
    j6, j7 = robot.joint("panda_joint6"), robot.joint("panda_joint7")
    never = [k for k, p in by_pair.items() if p.status == "never" and p.joints]
    assert len(never) >= 5
    q6s, q7s = rng.uniform(j6.lower, j6.upper, 300), rng.uniform(j7.lower, j7.upper, 300)
    for q6, q7 in zip(q6s, q7s, strict=True):
        world = posed({"panda_joint6": q6, "panda_joint7": q7})
        for a, b in never:
            assert not fcl_collide(world[a], world[b]), (a, b, q6, q7)
    for (a, b), pair in by_pair.items():
        if pair.status == "sometimes":
            world = posed(pair.witness)
            buried = (
                winding_inside(world[a], world[b].vertices[:50]).any()
                or winding_inside(world[b], world[a].vertices[:50]).any()
            )
            assert fcl_collide(world[a], world[b]) or buried, (a, b)


def test_srdf_without_a_robot_is_a_usage_error(tmp_path):
    from meshes import box

    box().export(tmp_path / "cube.stl")
    run = CliRunner().invoke(
        main,
        [str(tmp_path / "cube.stl"), "--srdf", str(tmp_path / "x.srdf"), "--no-cache", "-j", "1"],
    )
    assert run.exit_code == ExitStatus.USAGE
    assert "the inputs hold none" in run.stderr and not (tmp_path / "x.srdf").exists()


def test_coarse_pieces_with_their_pads_never_raise_the_distance_bound():
    """The box search poses each piece's coarse hull grown by its pad: at random placements of
    two panda links, the padded coarse distance never exceeds the full pieces' distance, and no
    coarse piece keeps more vertices than the icosphere has directions (162)."""
    from meshcheck.decompose import decompose_bodies
    from meshcheck.geometry import pack_convex
    from meshcheck.sweep.distances import coarse_pieces, piece_distances

    bodies = load_bodies([PANDA])
    by_name = {b.name.rpartition("#")[2]: k for k, b in enumerate(bodies)}
    chosen = [by_name["panda_link4"], by_name["panda_hand"]]
    pieces = decompose_bodies([bodies[k] for k in chosen], jobs=1)
    packs = []
    for body, ps in zip([bodies[k] for k in chosen], pieces, strict=True):
        inverse = np.linalg.inv(body.transform)
        local = [p @ inverse[:3, :3].T + inverse[:3, 3] for p in ps]
        coarse, pad = coarse_pieces(local, min_vertices=0)  # the panda's are under the bar
        assert all(len(c) <= 162 for c in coarse) and np.all(pad >= 0.0)
        packs.append((pack_convex(local, is_hull=True), pack_convex(coarse, is_hull=True), pad))
    rng = np.random.default_rng(3)
    ta = np.broadcast_to(np.eye(4), (200, 4, 4)).copy()
    tb = ta.copy()
    for k in range(200):
        rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        tb[k, :3, :3] = rotation * np.sign(np.linalg.det(rotation))
        tb[k, :3, 3] = rng.uniform(-0.3, 0.3, 3)
    reach = np.full(200, np.inf)
    (full_a, coarse_a, pad_a), (full_b, coarse_b, pad_b) = packs
    exact = piece_distances(full_a, full_b, ta, tb, reach)
    bound = piece_distances(coarse_a, coarse_b, ta, tb, reach, pad_a, pad_b)
    apart = exact > 0.0  # in contact, GJK without depth gives some value <= 0, not the depth
    assert np.all(bound[apart] <= exact[apart] + 1e-12) and np.all(bound[~apart] <= 0.0)
    assert np.any(apart) and not np.all(apart)  # both sides of contact were drawn
    # settle (the boxes' question, within reach or not): the same answer, from some piece pair
    for r in (0.01, 0.05, 0.2):
        reach = np.full(200, r)
        full = piece_distances(coarse_a, coarse_b, ta, tb, reach, pad_a, pad_b)
        settled = piece_distances(coarse_a, coarse_b, ta, tb, reach, pad_a, pad_b, settle=True)
        assert np.array_equal(settled <= reach, full <= reach)
        near = full <= reach
        assert np.all(settled[near] >= full[near]) and np.array_equal(settled[~near], full[~near])


# ------------------------------------------------------------------------------------------
# The work budget


def test_a_spent_budget_leaves_the_rest_undecided_and_changes_no_decided_class(tmp_path):
    """A chain of six links whose pairs are all proven never with the default budget: with a
    budget of 10,000 (a visited pair costs at least 4,096), the pairs visited first (links
    nearest the root) keep their class, the rest are counted undecided and unlisted, the work
    stops within a batch of the budget, the same budget gives the same answer twice, and the
    JSON report says the budget."""
    import json

    from meshes import chain_urdf

    path = write(tmp_path, chain_urdf(6))
    full = sweep(path)
    assert len(full) == 15 and all(p.status == "never" for p in full.values())

    def budgeted():
        settings = Settings(motion=Motion(sweep=(), budget=10_000))
        assembly = load_assembly([path], motion=settings.motion)
        (robot,) = sweep_bodies(assembly.bodies, assembly.mechanisms, settings)
        return robot

    robot = budgeted()
    assert robot == budgeted()
    assert robot.budget == 10_000 and 10_000 <= robot.work <= 10_000 + 4096
    assert 0 < len(robot.pairs) < 15 and robot.unswept == 15 - len(robot.pairs)
    assert robot.counts["undecided"] >= robot.unswept
    assert sum(robot.counts.values()) == 15
    for pair in robot.pairs:
        assert pair.status in (full[pair.a, pair.b].status, "undecided")
    swept = {(p.a, p.b) for p in robot.pairs}
    assert ("l0", "l1") in swept and ("l4", "l5") not in swept  # the root's links first
    assert "left unswept when the budget ran out" in robot.summary()

    args = [path, "--sweep", "--sweep-budget", "10000", "--format", "json", "--no-cache"]
    run = CliRunner().invoke(main, [*args, "--no-config", "-j", "1"])
    assert run.exit_code == 0, run.output
    doc = json.loads(run.stdout)
    assert doc["summary"]["sweep_budget"] == 10_000
    (entry,) = doc["sweeps"]
    assert (entry["budget"], entry["work"], entry["unswept"]) == (10_000, robot.work, robot.unswept)
    assert entry["counts"]["undecided"] == robot.counts["undecided"]
    text = CliRunner().invoke(main, [*args[:4], "--no-cache", "--no-config", "-j", "1"])
    assert f"work {robot.work:,} of the budget's 10,000" in " ".join(text.stdout.split())


@pytest.mark.parametrize(
    ("given", "message"),
    [
        (["--sweep-budget", "0"], "--sweep-budget"),
        (["--sweep-budget", "lots"], "--sweep-budget"),
        (["--config", "bad.toml"], "sweep_budget must be a whole number"),
    ],
)
def test_a_budget_that_is_not_a_positive_whole_number_is_a_usage_error(tmp_path, given, message):
    path = write(tmp_path, door(1.0))
    (tmp_path / "bad.toml").write_text('sweep_budget = "lots"\n')
    given = [str(tmp_path / g) if g.endswith(".toml") else g for g in given]
    run = CliRunner().invoke(main, [path, "--sweep", *given, "--no-cache", "-j", "1"])
    assert run.exit_code == ExitStatus.USAGE, run.output
    assert message in run.stderr and "Traceback" not in run.stderr


def test_the_configuration_sets_the_budget_and_the_option_wins(tmp_path):
    import json

    path = write(tmp_path, door(1.0))
    config = tmp_path / "meshcheck.toml"
    config.write_text("sweep_budget = 123456\n")
    base = [path, "--sweep", "--format", "json", "--config", str(config), "--no-cache", "-j", "1"]
    run = CliRunner().invoke(main, base)
    assert json.loads(run.stdout)["summary"]["sweep_budget"] == 123456
    run = CliRunner().invoke(main, [*base, "--sweep-budget", "654321"])
    assert json.loads(run.stdout)["sweeps"][0]["budget"] == 654321


# A chain of six links whose joints reach 1.6375 rad: the pairs three and four links apart pass
# within a hair of each other or collide, and each costs several times the least a pair costs.
NEAR_MISS_LIMIT = 1.6375


def budgeted_sweep(path: str, budget: int):
    settings = Settings(motion=Motion(sweep=(), budget=budget))
    assembly = load_assembly([path], motion=settings.motion)
    (robot,) = sweep_bodies(assembly.bodies, assembly.mechanisms, settings)
    return robot


@pytest.fixture(scope="module")
def near_miss_chain(tmp_path_factory):
    from meshes import chain_urdf

    path = write(tmp_path_factory.mktemp("chain"), chain_urdf(6, limit=NEAR_MISS_LIMIT))
    return path, budgeted_sweep(path, 400_000_000)


def test_the_near_miss_chain_has_every_class_and_costs_more_than_a_few_pairs(near_miss_chain):
    _, full = near_miss_chain
    assert full.counts["never"] >= 10 and full.counts["sometimes"] >= 2 and full.unswept == 0
    assert full.work > 15 * 4096


@hypothesis_settings(max_examples=25, derandomize=True, deadline=None)
@given(st.integers(1, 100_000), st.integers(1, 100_000))
def test_a_larger_budget_decides_what_a_smaller_one_does_and_never_changes_a_class(
    near_miss_chain, small, large
):
    """Against the run with the whole default budget: every pair a budget decides has the
    whole run's class (never proven apart when it is not), a larger budget decides every pair
    a smaller one does, each run counts all 15 pairs, and the work stops within one pair's
    least cost or one batch of boxes of the budget."""
    path, full = near_miss_chain
    small, large = sorted((small, large))
    classes = {(p.a, p.b): p.status for p in full.pairs}
    decided = {}
    for budget in (small, large):
        robot = budgeted_sweep(path, budget)
        assert sum(robot.counts.values()) == 15 and robot.unswept == 15 - len(robot.pairs)
        assert robot.work <= max(budget, 0) + 4096 + 1024 * 8
        if robot.unswept or any(p.status == "undecided" for p in robot.pairs):
            assert robot.work >= budget
        decided[budget] = {(p.a, p.b) for p in robot.pairs if p.status != "undecided"}
        for pair in robot.pairs:
            assert pair.status in (classes[pair.a, pair.b], "undecided")
    assert decided[small] <= decided[large]
