"""A link's envelope over the joints at the end of its chain (``sweep.envelope``): a known
answer the box search alone leaves undecided within a small box budget, and the envelopes'
distance bound never above the real meshes' distance (python-fcl, an independent forward
kinematics) at random poses of every joint, the enveloped ones included.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hypothesis_settings
from hypothesis import strategies as st
from test_sweep import PR2
from test_sweep_corners import hull_pair, real_distance, sweep_urdf

import meshcheck.sweep.search as search
from meshcheck.sweep.search import envelope_pair


def arm_and_wheel(gap: float) -> str:
    """Two links 0.5 m long (boxes 0.5 x 0.05 x 0.05 from their joint along x) turned about z
    by joints within -0.6..0.6 rad, and a wheel (a cylinder of radius 0.2, 0.1 thick) spinning
    on a continuous joint about the x axis, its face ``gap`` beyond the arm's reach. The arm's
    farthest point is its tip's corner, ``hypot(1, 0.025, 0.025)`` from the first joint; it
    meets the x axis, the wheel's, within the ranges."""
    box = '<origin xyz="0.25 0 0"/><geometry><box size="0.5 0.05 0.05"/></geometry>'
    face = float(np.linalg.norm([1.0, 0.025, 0.025])) + gap
    return "\n".join([
        '<robot name="arm_and_wheel">',
        '<link name="base"/>',
        '<link name="l1"><collision>' + box + "</collision></link>",
        '<link name="l2"><collision>' + box + "</collision></link>",
        '<link name="wheel"><collision><origin rpy="0 1.5707963267948966 0"/>'
        '<geometry><cylinder radius="0.2" length="0.1"/></geometry></collision></link>',
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        '<axis xyz="0 0 1"/><limit lower="-0.6" upper="0.6"/></joint>',
        '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>'
        '<origin xyz="0.5 0 0"/><axis xyz="0 0 1"/><limit lower="-0.6" upper="0.6"/></joint>',
        '<joint name="spin" type="continuous"><parent link="base"/><child link="wheel"/>'
        f'<origin xyz="{face + 0.05} 0 0"/><axis xyz="1 0 0"/></joint>',
        "</robot>",
    ])  # fmt: skip


def sweep_wheel(tmp_path, gap: float) -> dict:
    return sweep_urdf(tmp_path / "arm_and_wheel.urdf", arm_and_wheel(gap))


def test_an_arm_just_short_of_a_spinning_wheel_is_proven_never_in_a_tenth_of_the_boxes(
    tmp_path, monkeypatch
):
    """The arm's tip stops 1 cm short of the wheel's face at its straightest: never, in fewer
    than 6,000 boxes once the wheel's spin goes into its envelope, and in more than 30,000
    without: the spin is a full turn, the same pose at both corners of its range, and turns
    the rim 0.2 m per radian, so the search must cut it into many boxes under the arm's. 1 cm
    past the arm's reach the wheel is hit (sometimes)."""
    monkeypatch.setattr(search, "ENVELOPE_AFTER", 1_000)
    enveloped = sweep_wheel(tmp_path, 0.01)["l2", "wheel"]
    assert enveloped.status == "never" and enveloped.boxes < 6_000
    past = sweep_wheel(tmp_path, -0.01)["l2", "wheel"]
    assert past.status == "sometimes" and past.verdict == "interference"
    monkeypatch.setattr(search, "ENVELOPE_AFTER", 10**9)
    searched = sweep_wheel(tmp_path, 0.01)["l2", "wheel"]
    assert searched.status == "never" and searched.boxes > 30_000


# ------------------------------------------------------------------------------------------
# The envelopes' bound below the real meshes' distance

PAIRS = {
    # a caster's turn (continuous) against an arm whose forearm rolls (continuous) and whose
    # elbow, upper arm and shoulder go too when nothing limits how far the envelopes reach
    "caster": (PR2, "bl_caster_rotation_link", "r_forearm_link"),
    # the head's pan and tilt against the wrist's roll and flex
    "head": (PR2, "head_mount_link", "r_wrist_roll_link"),
}


@pytest.fixture(scope="module")
def enveloped_pairs():
    """Each pair of ``PAIRS`` (one convex piece per part, its hull), its ranges and meshes,
    and two envelope pairs: with every joint the envelopes can take (``margin`` unbounded),
    and with those whose envelopes reach 5 cm at most."""
    import warnings

    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the PR2's open meshes
        for key, spec in PAIRS.items():
            pair, (lower, upper), meshes = hull_pair(*spec)
            for margin in (np.inf, 0.05):
                made = envelope_pair(pair, lower, upper, margin)
                out[key, margin] = (pair, lower, upper, meshes, made)
    return out


def test_the_envelopes_take_the_continuous_joints_first(enveloped_pairs):
    """Known answer: with a 5 cm budget, the caster's turn and the forearm's roll (both
    continuous) go into their envelopes; the arm's limited joints, which swing the forearm
    through large arcs, stay in the search."""
    pair, _, _, _, (sub, _, _) = enveloped_pairs["caster", 0.05]
    gone = set(pair.names) - set(sub.names)
    assert {"bl_caster_rotation_joint", "r_forearm_roll_joint"} <= gone
    assert {"r_shoulder_pan_joint", "r_shoulder_lift_joint"} <= set(sub.names)


@hypothesis_settings(max_examples=30, derandomize=True, deadline=None)
@given(
    st.sampled_from(sorted(PAIRS)),
    st.sampled_from([np.inf, 0.05]),
    st.integers(0, 2**32 - 1),
)
def test_the_envelope_bound_is_never_above_the_real_distance(enveloped_pairs, key, margin, seed):
    """At random values of every joint, the envelopes' pieces placed at the values of the
    joints left (the enveloped ones held at their ranges' middle), less their pads, are no
    nearer than python-fcl's distance between the real meshes at the full pose."""
    pair, lower, upper, meshes, (sub, _, _) = enveloped_pairs[key, margin]
    rng = np.random.default_rng(seed)
    for values in rng.uniform(lower, upper, (4, len(lower))):
        kept = np.array([values[pair.names.index(n)] for n in sub.names])
        ta, tb, _ = sub.placements(kept[None, :])
        bound = float(sub.piece_distances(ta, tb, np.inf)[0])
        assert bound <= real_distance(pair, meshes, values) + 1e-9


def test_a_range_past_a_full_turn_is_one_turn(enveloped_pairs):
    """A revolute joint whose limits span a million radians (a hostile URDF) turns its link's
    envelope through one turn, no more copies than a continuous joint's, in well under a
    second."""
    import time

    from meshcheck.sweep.envelope import envelope

    pair, _, _, _, _ = enveloped_pairs["caster", np.inf]
    link = pair.links[pair.a]
    origin, direction = np.zeros(3), np.array([0.0, 0.0, 1.0])
    start = time.perf_counter()
    huge, huge_reach = envelope(link, origin, direction, -1e6, 1e6)
    assert time.perf_counter() - start < 1.0
    turn, turn_reach = envelope(link, origin, direction, -np.pi, np.pi)
    assert np.array_equal(huge.pack.points, turn.pack.points)
    assert np.array_equal(huge.pad, turn.pad) and huge_reach == turn_reach
