"""The sweep's compiled kernels against plain numpy and the batch GJK: piece distances at many
placements (``geometry.placed_distances``), the lever arms of the motion bound
(``geometry.farthest_from_lines``) and the chains' placements at many poses
(``geometry.chains``, against an independent forward kinematics); and the work budget's
accounting."""

from __future__ import annotations

import functools
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from robot_oracle import link_poses, read_robot
from test_sweep import PR2

from meshcheck.geometry import (
    concat_packs,
    farthest_from_lines,
    pack_convex,
    placed_distances,
    query_pairs,
)
from meshcheck.geometry.chains import chain_placements
from meshcheck.geometry.gjk import Status
from meshcheck.geometry.triangles import near_triangle_pairs
from meshcheck.load.robot import MOVABLE, chain_transforms, fold_chain
from meshcheck.load.urdf import parse_robot
from meshcheck.sweep.search import PAIR_WORK, WorkBudget


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.sign(np.linalg.det(q))


def _pieces(rng, count: int, spread: float) -> list[np.ndarray]:
    return [
        rng.normal(size=(int(rng.integers(1, 40)), 3)) * rng.uniform(0.05, 0.5)
        + rng.uniform(-spread, spread, 3)
        for _ in range(count)
    ]


def _by_query_pairs(pack_a, pack_b, relative, pad_a, pad_b) -> np.ndarray:
    """Every piece pair at every placement, b's points placed by numpy, GJK to the end."""
    out = []
    for t in relative:
        placed = pack_convex([p @ t[:3, :3].T + t[:3, 3] for p in np.split(
            pack_b.points, pack_b.starts[1:-1])], is_hull=True)  # fmt: skip
        both = concat_packs([pack_a, placed])
        ma, mb = len(pack_a.starts) - 1, len(placed.starts) - 1
        i, j = np.meshgrid(np.arange(ma), np.arange(mb), indexing="ij")
        pairs = np.stack([i.ravel(), ma + j.ravel()], axis=1)
        res = query_pairs(both, pairs, tolerance=0.0, depth=False)
        found = np.where(res.status == Status.UNDECIDED, np.minimum(res.distance, 0.0),
                         res.distance)  # fmt: skip
        out.append((found - pad_a[i.ravel()] - pad_b[j.ravel()]).min())
    return np.array(out)


@settings(max_examples=25, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reach=st.floats(0.0, 3.0), settle=st.booleans())
def test_placed_distances_agree_with_the_batch_gjk_on_every_piece_pair(seed, reach, settle):
    """Within reach the answer is the least padded piece distance (or, settled, some piece
    pair's within reach); beyond it, a bound no larger than that least distance."""
    rng = np.random.default_rng(seed)
    pack_a = pack_convex(_pieces(rng, int(rng.integers(1, 5)), 1.0), is_hull=False)
    pack_b = pack_convex(_pieces(rng, int(rng.integers(1, 5)), 1.0), is_hull=False)
    pad_a = rng.uniform(0.0, 0.05, len(pack_a.starts) - 1)
    pad_b = rng.uniform(0.0, 0.05, len(pack_b.starts) - 1)
    relative = np.tile(np.eye(4), (6, 1, 1))
    for t in relative:
        t[:3, :3], t[:3, 3] = _rotation(rng), rng.uniform(-2.0, 2.0, 3)
    exact = _by_query_pairs(pack_a, pack_b, relative, pad_a, pad_b)
    got, work = placed_distances(
        pack_a, pack_b, relative, np.full(6, reach), pad_a, pad_b, settle=settle
    )
    assert work >= 0
    scale = 1e-9 * (1.0 + np.abs(exact))
    near = exact <= reach
    assert np.all(got[~near] > reach - scale[~near])  # beyond reach: never within it
    if settle:
        assert np.all(got[near] <= reach + scale[near])
        assert np.all(got[near] >= exact[near] - scale[near])
    else:
        assert np.allclose(got[near], exact[near], rtol=1e-9, atol=1e-9)


def test_a_placement_that_is_not_finite_certifies_nothing():
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    pack = pack_convex([cube])
    relative = np.tile(np.eye(4), (2, 1, 1))
    relative[0, 0, 3] = np.nan
    relative[1, 0, 3] = 5.0
    got, _ = placed_distances(pack, pack, relative, np.full(2, 10.0), np.zeros(1), np.zeros(1))
    assert got[0] == -np.inf and got[1] == 4.0


@settings(max_examples=40, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_farthest_from_lines_is_the_largest_distance_to_each_line(seed):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(int(rng.integers(1, 30)), 3))
    placed = np.tile(np.eye(4), (5, 1, 1))
    for t in placed:
        t[:3, :3], t[:3, 3] = _rotation(rng), rng.normal(size=3)
    origins = rng.normal(size=(5, 3, 3))
    directions = rng.normal(size=(5, 3, 3))
    directions /= np.linalg.norm(directions, axis=2, keepdims=True)
    got = farthest_from_lines(points, placed, origins, directions)
    for e in range(5):
        world = points @ placed[e, :3, :3].T + placed[e, :3, 3]
        for t in range(3):
            d = world - origins[e, t]
            off = np.linalg.norm(np.cross(d, directions[e, t]), axis=1)
            assert got[e, t] == np.float64(off.max()) or abs(got[e, t] - off.max()) <= 1e-12 * (
                1.0 + off.max()
            )


def test_a_lever_that_is_not_a_number_is_infinite():
    placed = np.eye(4)[None].copy()
    placed[0, 0, 0] = np.nan
    got = farthest_from_lines(np.ones((2, 3)), placed, np.zeros((1, 1, 3)), np.ones((1, 1, 3)))
    assert got[0, 0] == np.inf


def test_the_budget_charges_at_least_a_pairs_least_cost_and_stops_when_spent():
    budget = WorkBudget(10 * PAIR_WORK)
    budget.charge(1)  # a pair that cost less still counts what visiting it costs
    assert budget.used == PAIR_WORK and budget.allowance == 9 * PAIR_WORK
    assert budget.pairs_left == 10
    budget.charge(9 * PAIR_WORK + 5)
    assert budget.allowance is None and budget.pairs_left == 1


@settings(max_examples=25, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reach=st.floats(0.0, 1.5), settle=st.booleans())
def test_placed_surface_distance_agrees_with_every_triangle_pair(seed, reach, settle):
    """Two small random meshes, one placed in the other's frame: within reach the answer is the
    least distance over every triangle pair (settled: some pair's within reach), beyond it a
    value above reach, as measuring every pair with ``pair_distances`` says."""
    import trimesh

    from meshcheck.geometry.triangles import pair_distances, placed_surface_distance

    rng = np.random.default_rng(seed)
    a = trimesh.creation.icosphere(1, radius=rng.uniform(0.2, 0.6))
    b = trimesh.creation.box(rng.uniform(0.1, 0.8, 3))
    relative = np.eye(4)
    relative[:3, :3], relative[:3, 3] = _rotation(rng), rng.uniform(-1.0, 1.0, 3)
    placed = b.vertices @ relative[:3, :3].T + relative[:3, 3]
    i, j = np.meshgrid(np.arange(len(a.faces)), np.arange(len(b.faces)), indexing="ij")
    every = np.stack([i.ravel(), j.ravel()], axis=1)
    exact = float(pair_distances(a.vertices, a.faces, placed, b.faces, every)[0].min())
    got, measured = placed_surface_distance(
        a.vertices, a.faces, b.vertices, b.faces, relative, reach, settle=settle
    )
    assert 0 <= measured <= len(every)
    if exact <= reach:
        if settle:
            assert exact - 1e-12 <= got <= reach + 1e-12
        else:
            assert abs(got - exact) <= 1e-12
    else:
        assert got > reach


@functools.cache
def _pr2():
    """The PR2 as meshcheck reads it and as the independent reading does."""
    with open(PR2, "rb") as f:
        robot = parse_robot(PR2, f.read())
    package = {"moveit_resources_pr2_description": os.path.dirname(os.path.dirname(PR2))}
    return robot, read_robot(PR2, package)


@settings(max_examples=10, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_chain_transforms_place_every_link_and_axis_as_a_pose_by_pose_reading(seed):
    """Every PR2 link (turns, the torso's slide, mimic fingers) and every movable joint's axis
    line above it, at five random poses in one call, against the independent reading's forward
    kinematics (``robot_oracle``: scipy's rotations, one pose at a time)."""
    robot, oracle = _pr2()
    rng = np.random.default_rng(seed)
    drawn = [
        {j.name: rng.uniform(max(j.lower, -np.pi), min(j.upper, np.pi)) for j in oracle.movable}
        for _ in range(5)
    ]
    expected = [link_poses(oracle, values) for values in drawn]
    by_child = {j.child: j for j in oracle.joints.values()}
    scale = 1000.0
    for link in robot.links:
        chain = robot.chain(link)
        poses = {}
        for joint in chain:
            if joint.type in MOVABLE:
                leader, multiplier, offset = oracle.joints[joint.name].mimic or (joint.name, 1, 0)
                poses[joint.name] = np.array([multiplier * v[leader] + offset for v in drawn])
        axes: dict = {}
        placed = chain_transforms(fold_chain(chain), poses, scale, len(drawn), axes)
        for e, links in enumerate(expected):
            want = links[link].copy()
            want[:3, 3] *= scale
            np.testing.assert_allclose(placed[e], want, atol=1e-9)
            for name, (points, directions) in axes.items():
                joint = oracle.joints[name]
                frame = links[joint.parent] @ joint.origin
                np.testing.assert_allclose(points[e], frame[:3, 3] * scale, atol=1e-9)
                np.testing.assert_allclose(directions[e], frame[:3, :3] @ joint.axis, atol=1e-12)
        assert set(axes) == {j.name for j in chain if j.type in MOVABLE}
        assert link == robot.root or by_child[link].name == chain[-1].name


def test_chain_placements_refuse_unknown_kinds_and_mismatched_shapes():
    one = np.eye(4)[None]
    with pytest.raises(ValueError, match="kinds"):
        chain_placements(one, [2], [[0, 0, 1.0]], np.eye(4), [[0.5]], 1.0)
    with pytest.raises(ValueError, match="shapes"):
        chain_placements(one, [0, 0], [[0, 0, 1.0]] * 2, np.eye(4), [[0.5, 0.5]], 1.0)
    with pytest.raises(ValueError, match="columns"):
        chain_placements(one, [0], [[0, 0, 1.0]], np.eye(4), [[0.5, 0.5]], 1.0)
    placed, points, _ = chain_placements(
        np.zeros((0, 4, 4)), np.zeros(0), np.zeros((0, 3)), np.eye(4), np.zeros((3, 0)), 2.0
    )
    assert placed.shape == (3, 4, 4) and points.shape == (3, 0, 3)
    np.testing.assert_array_equal(placed, np.broadcast_to(np.eye(4), (3, 4, 4)))


@settings(max_examples=25, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reach=st.floats(0.0, 1.0))
def test_near_triangle_pairs_are_every_pair_whose_boxes_come_within_reach(seed, reach):
    """Against every triangle pair's boxes compared by numpy, ``b`` placed by numpy."""
    rng = np.random.default_rng(seed)
    va, vb = rng.normal(size=(30, 3)), rng.normal(size=(25, 3)) * 0.7
    fa, fb = rng.integers(0, 30, (40, 3)), rng.integers(0, 25, (35, 3))
    relative = np.eye(4)
    relative[:3, :3], relative[:3, 3] = _rotation(rng), rng.normal(size=3)
    found = near_triangle_pairs(va, fa, vb, fb, relative, reach)
    placed = vb @ relative[:3, :3].T + relative[:3, 3]
    alo, ahi = va[fa].min(axis=1), va[fa].max(axis=1)
    blo, bhi = placed[fb].min(axis=1), placed[fb].max(axis=1)
    gap = np.maximum(alo[:, None] - bhi[None], blo[None] - ahi[:, None])  # (40, 35, 3)
    expected = np.argwhere(np.all(gap <= reach, axis=2))
    assert sorted(map(tuple, found.tolist())) == sorted(map(tuple, expected.tolist()))
    with pytest.raises(ValueError, match="finite"):
        near_triangle_pairs(va, fa, vb, fb, np.full((4, 4), np.nan), reach)
