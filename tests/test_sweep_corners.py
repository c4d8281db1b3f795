"""The corner test of a box of joint values (``LinkPair.corner_bounds``): a known answer the
first-order bound alone cannot reach within a small box budget, and its bound never above the
real meshes' distance (python-fcl) anywhere in random boxes of the panda's and the PR2's joints.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import settings as hypothesis_settings
from hypothesis import strategies as st
from meshes import fcl_distance
from test_sweep import PANDA, PR2, hull_links

import meshcheck.sweep.search as search
from meshcheck.load import load_assembly
from meshcheck.load.robot import link_transforms, with_mimics
from meshcheck.motion import Motion
from meshcheck.settings import Settings
from meshcheck.sweep import sweep_bodies
from meshcheck.sweep.kinematics import joint_ranges, link_sides, motion_weights
from meshcheck.sweep.search import LinkPair


def arm(wall: float) -> str:
    """Three links 1 m long (boxes 1 x 0.05 x 0.05 from their joint along x) turned about z
    by joints every metre, each within -0.6..0.6 rad, and a wall (a box 0.1 m thick) whose face
    is ``wall`` from the first joint along x. The arm's farthest point is its tip's corner,
    ``hypot(3, 0.025, 0.025)`` from the first joint; it reaches the x axis within the ranges."""
    box = '<origin xyz="0.5 0 0"/><geometry><box size="1 0.05 0.05"/></geometry>'
    links = [f'<link name="l{k}"><collision>{box}</collision></link>' for k in (1, 2, 3)]
    joints = [
        f'<joint name="j{k}" type="revolute"><parent link="{parent}"/><child link="l{k}"/>'
        f'<origin xyz="{0 if k == 1 else 1} 0 0"/><axis xyz="0 0 1"/>'
        '<limit lower="-0.6" upper="0.6"/></joint>'
        for k, parent in ((1, "base"), (2, "l1"), (3, "l2"))
    ]
    return "\n".join([
        '<robot name="arm">',
        '<link name="base"/>',
        f'<link name="wall"><collision><origin xyz="{wall + 0.05} 0 0"/>'
        '<geometry><box size="0.1 2 2"/></geometry></collision></link>',
        '<joint name="fix" type="fixed"><parent link="base"/><child link="wall"/></joint>',
        *links,
        *joints,
        "</robot>",
    ])  # fmt: skip


REACH = float(np.linalg.norm([3.0, 0.025, 0.025]))


def sweep_arm(tmp_path, wall: float) -> dict:
    return sweep_urdf(tmp_path / "arm.urdf", arm(wall))


def sweep_urdf(path, text: str) -> dict:
    """Every link pair's ``PairSweep`` of the robot ``text``, written to ``path``, swept over
    all its joints."""
    path.write_text(text)
    settings = Settings(motion=Motion(sweep=()))
    assembly = load_assembly([str(path)], motion=settings.motion)
    (robot,) = sweep_bodies(assembly.bodies, assembly.mechanisms, settings)
    return {(p.a, p.b): p for p in robot.pairs}


def test_an_arm_just_short_of_a_wall_is_proven_never_by_its_corners(tmp_path, monkeypatch):
    """The arm's tip stops 1 cm short of the wall at its straightest: never, within 6,000 boxes (it
    takes about 4,000, its corner tests counted). The first-order bound alone (corners of no joint)
    leaves it undecided: near the straight pose the tip moves 3 m per radian of the first joint, but
    only ``3 h**2 / 2`` towards the wall; 1 cm past its reach the wall is hit (sometimes)."""
    monkeypatch.setattr(search, "MAX_BOXES", 6_000)
    monkeypatch.setattr(search, "CORNER_AFTER", 0)  # from the first box
    assert sweep_arm(tmp_path, REACH + 0.01)["l3", "wall"].status == "never"
    past = sweep_arm(tmp_path, REACH - 0.01)["l3", "wall"]
    assert past.status == "sometimes" and past.verdict == "interference"
    monkeypatch.setattr(search, "CORNER_JOINTS", 0)
    monkeypatch.setattr(search, "SEPARATE_SIDE_JOINTS", 0)
    assert sweep_arm(tmp_path, REACH + 0.01)["l3", "wall"].status == "undecided"


# ------------------------------------------------------------------------------------------
# The bound below the real meshes' distance


def hull_pair(urdf: str, a: str, b: str):
    """A ``LinkPair`` of links ``a``, ``b`` with one convex piece per part, its hull (so the
    real meshes lie inside the pieces), the pair's joint ranges, and its meshes."""
    robot, bodies, base, swept, links = hull_links(urdf, only=(a, b))
    radius = {n: link.radius for n, link in links.items()}
    points = {n: link.points for n, link in links.items()}
    names = sorted(motion_weights(robot, (a, b), radius, swept, base, 1.0, points))
    sides = link_sides(robot, (a, b), links, names, swept, base, 1.0)
    pair = LinkPair(robot, a, b, names, sides, base, 1.0, 0.0, links, bodies)
    meshes = {n: trimesh.Trimesh(links[n].vertices, links[n].faces, process=False) for n in (a, b)}
    return pair, joint_ranges(robot, names), meshes


PAIRS = {
    # six joints of the panda's arm between them
    "panda": (PANDA, "panda_link1", "panda_hand"),
    # the PR2's gripper fingers: mimic joints leading several joints, and the torso's slide
    # under the arm
    "fingers": (PR2, "l_gripper_l_finger_tip_link", "l_gripper_r_finger_tip_link"),
    "torso": (PR2, "base_link", "l_forearm_link"),
    # one arm's upper arm roll link against the other's elbow: no joint moves both, so each
    # link's copies are over its own corner joints
    "arms": (PR2, "l_upper_arm_roll_link", "r_elbow_flex_link"),
}


@pytest.fixture(scope="module")
def hull_pairs():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the PR2's open meshes
        return {key: hull_pair(*spec) for key, spec in PAIRS.items()}


def random_box(rng, lower: np.ndarray, upper: np.ndarray, size: float):
    """(centre, half-widths, lo, hi) of a random box within ``lower..upper``, each joint's
    half-width up to ``size`` of its range."""
    half = rng.uniform(0.0, size, len(lower)) * (upper - lower)
    centre = rng.uniform(lower + half, upper - half)
    return centre, half, centre - half, centre + half


def corner_bound(pair: LinkPair, lo: np.ndarray, hi: np.ndarray, separate: bool = False) -> float:
    """The corner test's lower bound on the links' distance over the box ``lo..hi``."""
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    axes: dict = {}
    ta, tb, _ = pair.placements(centre[None, :], axes)
    rates = pair.joint_rates(ta, tb, axes, half[None, :])
    chosen, grown, _ = pair.corner_plan(half[None, :], rates, separate=separate)
    return float(pair.corner_bounds(lo[None, :], hi[None, :], chosen, grown, settle=False)[0])


def real_distance(pair: LinkPair, meshes: dict, values: np.ndarray) -> float:
    """python-fcl's distance between the two links' real meshes at the free joints' values."""
    robot = pair.robot
    pose = {n: v for n, v in pair.base.items() if robot.joint(n).mimic is None}
    pose.update(zip(pair.names, values, strict=True))
    placed = link_transforms(robot, with_mimics(robot, pose))  # mimic joints follow
    a, b = (meshes[n].copy().apply_transform(placed[n]) for n in (pair.a, pair.b))
    return fcl_distance(a, b)


@hypothesis_settings(max_examples=30, derandomize=True, deadline=None)
@given(
    st.sampled_from(sorted(PAIRS)),
    st.floats(0.002, 0.5),
    st.integers(0, 2**32 - 1),
    st.booleans(),
)
def test_the_corner_bound_is_never_above_the_real_distance_in_its_box(
    hull_pairs, key, size, seed, separate
):
    """For a random box (each joint's half-width up to ``size`` of its range), the corner
    test's bound (corners over the joints that move most, or with ``separate`` over each
    link's own) is at most python-fcl's distance between the real meshes at the box's
    corners, its centre and random poses within it."""
    pair, (lower, upper), meshes = hull_pairs[key]
    rng = np.random.default_rng(seed)
    centre, half, lo, hi = random_box(rng, lower, upper, size)
    bound = corner_bound(pair, lo, hi, separate)
    poses = [centre, lo, hi, *(centre + half * rng.uniform(-1, 1, (3, len(lower))))]
    poses.append(np.where(rng.random(len(lower)) < 0.5, lo, hi))
    for values in poses:
        assert bound <= real_distance(pair, meshes, values) + 1e-9


def test_the_corner_bound_is_tight_on_small_boxes(hull_pairs):
    """Known answer: on boxes 0.01 of each range wide about a pose where the panda's hand is
    clear of link 1 by half a metre, the corner bound is positive and its slack below the real
    distance at the centre is less than a quarter of the first-order bound's."""
    pair, (lower, upper), meshes = hull_pairs["panda"]
    centre = 0.5 * (lower + upper)
    half = 0.005 * (upper - lower)
    lo, hi = centre - half, centre + half
    exact = real_distance(pair, meshes, centre)
    bound = corner_bound(pair, lo, hi)
    axes: dict = {}
    ta, tb, _ = pair.placements(centre[None, :], axes)
    first = exact - float(half @ pair.box_weights(ta, tb, axes, half[None, :])[0])
    assert exact > 0.05 and 0.0 < bound <= exact
    assert exact - bound < 0.25 * (exact - first)


@hypothesis_settings(max_examples=30, derandomize=True, deadline=None)
@given(
    st.sampled_from(sorted(PAIRS)),
    st.floats(0.002, 0.5),
    st.integers(0, 2**32 - 1),
    st.booleans(),
)
def test_the_interpolation_error_is_within_its_bound(hull_pairs, key, size, seed, separate):
    """The lemma the corner test rests on, for every hull point of both links at random poses
    ``q`` of a random box: the point's distance from the multilinear interpolant of its
    corner positions (the chosen joints at their extremes, the others at the centre), summed
    over the two links, is at most the plan's ``G_a + G_b``."""
    pair, (lower, upper), _ = hull_pairs[key]
    rng = np.random.default_rng(seed)
    centre, half, lo, hi = random_box(rng, lower, upper, size)
    axes: dict = {}
    ta, tb, _ = pair.placements(centre[None, :], axes)
    rates = pair.joint_rates(ta, tb, axes, half[None, :])
    chosen, grown, _ = pair.corner_plan(half[None, :], rates, separate=separate)
    chosen = chosen[0]
    bits = (np.arange(2 ** len(chosen))[:, None] >> np.arange(len(chosen))) & 1
    corners = np.repeat(centre[None, :], len(bits), axis=0)
    corners[:, chosen] = np.where(bits == 1, hi[chosen], lo[chosen])
    ca, cb, _ = pair.placements(corners)
    for q in centre + half * rng.uniform(-1, 1, (4, len(lower))):
        t = np.where(half[chosen] > 0, (q[chosen] - lo[chosen]) / (2 * half[chosen]), 0.5)
        weights = np.prod(np.where(bits == 1, t, 1 - t), axis=1)
        qa, qb, _ = pair.placements(q[None, :])
        error = 0.0
        for link, at_q, at_corners in ((pair.a, qa[0], ca), (pair.b, qb[0], cb)):
            local = pair.links[link].points
            exact = local @ at_q[:3, :3].T + at_q[:3, 3]
            copies = (
                np.einsum("nj,kij->kni", local, at_corners[:, :3, :3]) + at_corners[:, None, :3, 3]
            )
            interpolated = np.einsum("k,kni->ni", weights, copies)
            error += np.linalg.norm(exact - interpolated, axis=1).max()
        assert error <= grown[0] + 1e-9


def pocket_wall(path) -> str:
    """The three-link arm of ``arm`` before a wall with a wide pocket, as one mesh (so its one
    convex piece, its hull, fills the pocket): a back plate whose face is 1 cm past the arm's
    reach along x, and two jaws that stand out of it around the arm's tip, outside the sphere
    the arm's points stay in (their nearest point is about 4.6 cm past it). Never: but the tip
    lies inside the wall's hull near the straight pose, so only the real triangles prove it."""
    back = trimesh.creation.box((0.1, 3.0, 2.0))
    back.apply_translation((REACH + 0.01 + 0.05, 0.0, 0.0))
    jaws = []
    for side in (1.0, -1.0):
        jaw = trimesh.creation.box((0.31, 0.2, 2.0))
        jaw.apply_translation((REACH - 0.2 + 0.155, side * 1.3, 0.0))
        jaws.append(jaw)
    trimesh.util.concatenate([back, *jaws]).export(path / "wall.stl")
    text = arm(REACH + 0.01)
    return text.replace(
        '<geometry><box size="0.1 2 2"/></geometry>',
        '<geometry><mesh filename="wall.stl"/></geometry>',
    ).replace(f'<origin xyz="{REACH + 0.01 + 0.05} 0 0"/><geometry><mesh', "<geometry><mesh")


def test_a_tip_in_a_pocket_its_wall_hull_fills_is_proven_never_by_its_triangles(
    tmp_path, monkeypatch
):
    """The wall's one convex piece (its hull) overlaps the arm's tip wherever the tip is near
    its reach, so the pieces' corner test cannot close those boxes; the triangles' corner test
    (``LinkPair.triangle_corner_bounds``) does, within 6,000 boxes. Without it the pair is
    undecided there (first order, the triangles need boxes 3 m per radian of the first joint
    small)."""
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(pocket_wall(tmp_path))
    pair, (lower, upper), meshes = hull_pair(str(urdf), "l3", "wall")
    straight = np.zeros(len(lower))
    ta, tb, _ = pair.placements(straight[None, :])
    assert pair.piece_distances(ta, tb, np.inf)[0] < 0.0  # the hull holds the tip
    assert real_distance(pair, meshes, straight) == pytest.approx(REACH + 0.01 - 3.0, abs=1e-6)
    monkeypatch.setattr(search, "MAX_BOXES", 6_000)
    monkeypatch.setattr(search, "CORNER_AFTER", 0)
    found = search.sweep_pair(pair, lower, upper, 0.001)
    assert found.status == "never"
    monkeypatch.setattr(
        search.LinkPair,
        "triangle_corner_bounds",
        lambda self, lo, *args: (np.full(len(lo), -np.inf), len(lo)),
    )
    again, *_ = hull_pair(str(urdf), "l3", "wall")
    assert search.sweep_pair(again, lower, upper, 0.001).status == "undecided"


@hypothesis_settings(max_examples=30, derandomize=True, deadline=None)
@given(
    st.sampled_from(sorted(PAIRS)),
    st.floats(0.002, 0.2),
    st.floats(0.1, 0.9),
    st.integers(0, 2**32 - 1),
)
def test_a_box_the_triangles_corner_test_clears_is_clear_everywhere_in_it(
    hull_pairs, key, size, share, seed
):
    """For a random box and a tolerance a random ``share`` of the real distance at its
    centre, a box ``LinkPair.triangle_corner_bounds`` certifies (above the tolerance) has
    python-fcl's distance between the real meshes above the tolerance at its centre, its
    corners and random poses within it."""
    import dataclasses

    pair, (lower, upper), meshes = hull_pairs[key]
    rng = np.random.default_rng(seed)
    centre, half, lo, hi = random_box(rng, lower, upper, size)
    exact = real_distance(pair, meshes, centre)
    pair = dataclasses.replace(pair, tolerance=share * exact)
    axes: dict = {}
    ta, tb, _ = pair.placements(centre[None, :], axes)
    rates = pair.joint_rates(ta, tb, axes, half[None, :])
    chosen, grown, _ = pair.corner_plan(half[None, :], rates)
    first = float(half @ pair.box_weights(ta, tb, axes, half[None, :])[0]) + pair.tolerance
    (bound,), measured = pair.triangle_corner_bounds(
        lo[None], hi[None], chosen, grown, ta, tb, np.array([first])
    )
    assert measured == 1
    if bound > pair.tolerance:  # both ways happen among the examples
        poses = [centre, lo, hi, *(centre + half * rng.uniform(-1, 1, (3, len(lower))))]
        poses.append(np.where(rng.random(len(lower)) < 0.5, lo, hi))
        for values in poses:
            assert real_distance(pair, meshes, values) > pair.tolerance


def test_corners_over_each_links_own_joints_when_no_joint_moves_both(hull_pairs):
    """Known answer: one arm's upper arm roll link against the other's elbow (three joints
    and four, none shared): with ``separate`` the corner test takes all seven, each link's
    copies over its own (8 and 16); without, the five that move most. A gripper's two
    fingers, moved by one joint they share, are not such a pair."""
    pair, (lower, upper), _ = hull_pairs["arms"]
    assert pair.has_separate_sides()
    centre, half = 0.5 * (lower + upper), 0.01 * (upper - lower)
    axes: dict = {}
    ta, tb, _ = pair.placements(centre[None, :], axes)
    rates = pair.joint_rates(ta, tb, axes, half[None, :])
    both, _, _ = pair.corner_plan(half[None, :], rates, separate=True)
    assert sorted(both[0].tolist()) == list(range(7))
    plain, _, _ = pair.corner_plan(half[None, :], rates)
    assert plain.shape == (1, search.CORNER_JOINTS)
    lo, hi = centre - half, centre + half
    _, counts = pair.corner_placements(lo[None], hi[None], both)
    assert [int(c[0]) for c in counts] == [8, 16]
    fingers, _, _ = hull_pairs["fingers"]
    assert not fingers.has_separate_sides()


def test_the_second_search_gives_its_envelopes_their_own_box_cap(hull_pairs, monkeypatch):
    """A pair of separate chains left undecided by its first search (here by a cap of 600
    boxes, envelopes tried from 200) is searched again with corners over each link's own
    joints, and its envelopes get ``SEPARATE_ENVELOPE_BOXES``, not the first search's
    ``ENVELOPE_BOXES``: the PR2's arms, whose roll links pass 7-8 mm apart, are proven only
    over the envelopes of both roll joints, and only within the second search's cap
    (``bench/sweep.py --robot pr2``)."""
    pair, (lower, upper), _ = hull_pairs["arms"]
    pair = dataclasses.replace(pair, tolerance=1e-5, envelopes={})
    monkeypatch.setattr(search, "MAX_BOXES", 600)
    monkeypatch.setattr(search, "ENVELOPE_AFTER", 200)
    monkeypatch.setattr(search, "SEPARATE_BOXES", 2000)
    monkeypatch.setattr(search, "ENVELOPE_BOXES", 100)
    monkeypatch.setattr(search, "SEPARATE_ENVELOPE_BOXES", 200)
    caps, proof = [], search.envelope_proof

    def recorded(*args, **kwargs):
        caps.append((kwargs["separate"], kwargs["max_boxes"]))
        return proof(*args, **kwargs)

    monkeypatch.setattr(search, "envelope_proof", recorded)
    found = search.sweep_pair(pair, lower, upper, 1e-4)
    assert caps == [(False, 100), (True, 200)], found
