"""The search over one link pair's joint values: never proven box by box, sometimes shown by a
witness pose the real meshes confirm.

A box of joint values is evaluated at its centre: the links' distance there, less how far any
point can move within the box (``kinematics.box_weights``), either certifies the whole box free
of contact or, for a pair that has needed many boxes, the hulls of the links' pieces at the
box's corners, less the interpolation's second-order error (``LinkPair.corner_bounds``), may,
and where the pieces cannot (they overlap where the real meshes pass close), the real meshes'
triangles at the corners the same way (``LinkPair.triangle_corner_bounds``); else the box is
halved. A pair still open after many boxes may be proven over its links'
envelopes, the joints at the ends of their chains turned through their ranges instead of
searched (``envelope_proof``, ``envelope.envelope``). Witnesses are looked for before the proof
(seeded samples), among the nearest box centres, and by a descent from them
(``descent_witness``).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..geometry import copied_distances, triangle_pack
from ..geometry.triangles import near_triangle_pairs
from ..load import Body
from ..load.robot import MOVABLE, ROTARY, Joint, Robot, chain_transforms, fold_chain
from ..results import PairSweep, SweepStatus, Verdict
from ..verify.pair import verify_pair
from .distances import LinkGeometry, piece_distances, surface_distance
from .envelope import envelope, steps
from .kinematics import (
    LinkSide,
    box_weights,
    combined_weights,
    joint_rates,
    joints_below_common,
    link_sides,
    side_bounds,
)

#: Boxes of joint values one link pair may evaluate before it is left undecided (the panda's
#: link 0 and link 4 need 71,579; bench/sweep.py on the PR2 sets the time against 10,000
#: python-fcl samples).
MAX_BOXES = 100_000
#: Boxes evaluated in one compiled call.
BATCH = 1024
#: Boxes whose motion bound is below this fraction of the smaller link's size, and whose
#: coarse pieces do not prove them apart, are measured on the real meshes' triangles.
FINE_REACH = 0.02
#: Poses drawn (fixed seed) to look for a witness before the proof starts, and how many of the
#: closest are re-checked on the real meshes.
SAMPLES = 256
SAMPLE_CHECKS = 4
#: Candidate witnesses re-checked on the real meshes per link pair, deepest piece overlap first.
MAX_WITNESS_CHECKS = 24
#: A pair not decided after this many boxes looks for a witness by descending the pieces'
#: distance from the nearest box centres (``descent_witness``): how many, steps, tries; and
#: again, from the centres nearest by then, each time the boxes grow by ``DESCENT_GROWTH``.
#: Three of the PR2's head-mount and wrist pairs collide only where the head is tilted and
#: the arm raised to their limits: from the nearest box centres ten steps do not reach it,
#: thirty do. A descent stops after ``DESCENT_SETTLE`` steps once some pose's pieces overlap
#: (most colliding pairs are there by then: thirty steps for every descent cost the PR2's
#: sometimes pairs half their time again, bench/sweep.py) or once every start's step has
#: shrunk to ``1 / DESCENT_SETTLED`` of its first (each start settled in its minimum).
DESCENT_AFTER = 4096
DESCENT_GROWTH = 4
DESCENT_STARTS = 8
DESCENT_STEPS = 30
DESCENT_SETTLE = 10
DESCENT_SETTLED = 64
DESCENT_TRIES = 32
#: The least work a link pair visited costs (``WorkBudget``), and what a check on the real
#: meshes costs besides its triangles over 64: the fixed cost of a pair's set-up and of one
#: ``verify_pair`` call, in the currency of poses and GJK queries (a 3,000-link chain of fixed
#: joints visits a pair in about 2 ms, the box search does about a million units of work a
#: second), so that the budget bounds the time of a robot of many cheap pairs too.
PAIR_WORK = 4096
VERIFY_WORK = 1024
#: What a pair of a ``[[joint]]`` mechanism that no swept joint moves costs: it is passed over
#: (the check judged it at the pose) after a few microseconds, never set up.
SKIP_WORK = 64

#: The joints a box's corner test (``LinkPair.corner_bounds``) takes corners of: those that
#: contribute most to its first-order bound, at most this many (2**CORNER_JOINTS copies of
#: each piece): each costs more per box, and each clears boxes ``h / 2`` times wider along its
#: joint; on the PR2's palm and shoulder (5 joints) five needed a ninth of the boxes three did.
CORNER_JOINTS = 5
#: A pair undecided after ``MAX_BOXES`` whose links no free joint moves both (two arms, a
#: head and an arm) is searched again, within ``SEPARATE_BOXES`` more, with each link's
#: copies over its own corner joints: up to ``SEPARATE_SIDE_JOINTS`` on each side,
#: ``SEPARATE_CORNER_JOINTS`` in all (the copies grow as the sum of the sides', 4 + 64 for
#: the PR2's head and a wrist, 8 joints all at corners, so only second-order error is left);
#: its envelopes (``envelope_proof``) may take ``SEPARATE_ENVELOPE_BOXES``. Only those left
#: undecided pay for the dearer copies: the PR2 has hundreds of such pairs (casters, head,
#: arms), most decided within the first search. On the PR2 (bench/sweep.py --robot pr2
#: --rows), the head mount and the Kinect against a forearm or wrist take 625,000 to 702,000
#: boxes all told; one arm's shoulder lift or upper arm roll link against the other's forearm
#: roll link, proven over the envelopes of both roll joints in the second search (not within
#: the first search's ``ENVELOPE_BOXES``), 254,000 to 273,000.
SEPARATE_CORNER_JOINTS = 8
SEPARATE_SIDE_JOINTS = 6
SEPARATE_BOXES = 500_000
SEPARATE_ENVELOPE_BOXES = 131_072
#: What one box's corner test counts for against ``MAX_BOXES``: about its time in boxes
#: evaluated at their centre alone (``bench/sweep.py --robot pr2 --pair
#: l_gripper_palm_link:l_shoulder_lift_link``: 0.06 ms a box, 0.77 ms a corner test of 32 copies).
CORNER_BOXES = 12
#: Boxes given the corner test in one compiled call: the work is checked against the pair's
#: allowance between them, so a pair stops within one such call of it.
CORNER_BATCH = 32
#: Boxes a link pair evaluates by the first-order bound alone before the corner test joins
#: in: most pairs are decided within them, where the corner test's copies cost more than the
#: boxes they save.
CORNER_AFTER = 4096

#: A box whose pieces' corner test fails (or is not tried: they overlap at its centre) gets
#: the real triangles' (``LinkPair.triangle_corner_bounds``) when its first-order bound is at
#: most this fraction of the larger link's size and at most ``MAX_TRIANGLE_PAIRS`` triangle
#: pairs come within that bound at its centre; larger boxes are split first (a box as large
#: as a link pairs most of both links' triangles). It counts as ``CORNER_BOXES`` boxes: one
#: costs about as much as the pieces' corner test (0.9 ms on the PR2's forearm and palm).
TRIANGLE_CORNER_REACH = 0.25
MAX_TRIANGLE_PAIRS = 20_000

#: A pair still open after this many boxes tries to prove never over its links' envelopes
#: (``envelope_proof``), within ``ENVELOPE_BOXES`` more; the envelopes may reach
#: ``ENVELOPE_SHARE`` of the nearest centre distance so far beyond the links.
ENVELOPE_AFTER = 8192
ENVELOPE_BOXES = 65_536
ENVELOPE_SHARE = 0.9

#: The real meshes' statuses that make a pose a witness.
COLLIDING = (Verdict.INTERFERENCE, Verdict.TOUCHING)


@dataclass
class LinkPair:
    """What one link pair's sweep needs.

    Attributes
    ----------
    robot : Robot
    a, b : str
        The links, ``a < b``.
    names : list of str
        The free joints: the swept leading joints that move one link relative to the other.
    sides : (LinkSide, LinkSide)
        Each link's joints below the pair's common ancestor (``kinematics.link_sides``).
    base : dict of str -> float
        Every movable joint's value at the run's pose.
    scale : float
        Report units per unit of the robot's lengths.
    tolerance : float
        Touching tolerance, report units.
    links : dict of str -> LinkGeometry
    bodies : sequence of Body
        The run's parts.
    work : int
        The work done so far (``WorkBudget``): a pose costs its free joints (at least 1), the
        distances their GJK queries and triangle pairs, a real-mesh check ``VERIFY_WORK`` and
        its triangles over 64.
    allowance : float
        The work it may do (``sweep_pair``); past it, distances are the pieces' bounds alone.
    fine : bool
        Whether boxes small enough are measured on the real meshes' triangles
        (``distances``); an envelope's pair (``envelope_pair``) has no triangles at its poses.
    envelopes : dict
        The links' envelopes made so far, shared by a robot's pairs (``envelope_pair``).
    """

    robot: Robot
    a: str
    b: str
    names: list[str]
    sides: tuple[LinkSide, LinkSide]
    base: dict
    scale: float
    tolerance: float
    links: dict[str, LinkGeometry]
    bodies: Sequence[Body]
    work: int = 0
    allowance: float = np.inf
    fine: bool = True
    envelopes: dict = field(default_factory=dict)

    def __post_init__(self):
        self.chains = joints_below_common(self.robot, (self.a, self.b))
        self.folded = tuple(fold_chain(chain) for chain in self.chains)

    def placements(self, values: np.ndarray, axes: dict | None = None):
        """(ta, tb, poses): the links' placements at the rows of ``values`` in the frame of
        their common ancestor (distances, and the motion bound, depend only on where one link
        lies relative to the other, so the joints above it are never composed) and every
        joint's values there; each movable joint's axis line below it goes to ``axes`` when
        given."""
        poses = chain_poses(self.robot, self.base, self.names, values, self.chains)
        count = len(values)
        self.work += count * max(len(self.names), 1)
        ta = chain_transforms(self.folded[0], poses, self.scale, count, axes)
        tb = chain_transforms(self.folded[1], poses, self.scale, count, axes)
        return ta, tb, poses

    def side_placements(self, values: np.ndarray, k: int) -> np.ndarray:
        """Link ``k``'s (0: ``a``) placements alone at the rows of ``values``
        (``placements``)."""
        poses = chain_poses(self.robot, self.base, self.names, values, self.chains[k : k + 1])
        self.work += len(values) * max(len(self.names), 1)
        return chain_transforms(self.folded[k], poses, self.scale, len(values))

    def box_weights(self, ta, tb, axes: dict, half: np.ndarray) -> np.ndarray:
        """(E, n) bounds on how fast a unit change of each free joint moves any point of the
        two links within the boxes of half-widths ``half`` about ``ta``, ``tb``
        (``kinematics.box_weights``)."""
        return box_weights(self.sides, ta, tb, axes, half)

    def joint_rates(self, ta, tb, axes: dict, half: np.ndarray):
        """Each side's bound per term of its joints (``kinematics.joint_rates``)."""
        return joint_rates(self.sides, ta, tb, axes, half)

    def corner_plan(
        self, half: np.ndarray, rates, *, separate: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Which joints of each box of half-widths ``half`` the corner test takes corners of,
        how far its bound falls below the hulls' distance, and the terms to split by.

        Returns
        -------
        chosen : (E, m) int64
            The ``CORNER_JOINTS`` (at most) free joints that contribute most to each box's
            first-order bound (``rates``, ``kinematics.joint_rates``); with ``separate``, when
            no free joint moves both links, up to ``SEPARATE_SIDE_JOINTS`` of each link's own
            joints, ``SEPARATE_CORNER_JOINTS`` in all (each link's copies are over its own
            corner joints only, so the copies grow as the sum of the two sides', not the
            product).
        grown : (E,) float64
            ``G_a + G_b`` (``corner_bounds``).
        split : (E, n) float64
            ``split * half`` are the terms of ``grown`` per free joint (``halve_boxes``).
        """
        bounds = [
            side_bounds(side, r, half.shape) for side, r in zip(self.sides, rates, strict=True)
        ]
        first = bounds[0][0] + bounds[1][0]
        order = np.argsort(-(half * first), axis=1, kind="stable")
        moves = self.moving_joints
        if not separate or np.any(moves[0] & moves[1]):
            chosen = order[:, : min(CORNER_JOINTS, half.shape[1])]
        else:  # each side's copies are over its own joints: up to SEPARATE_SIDE_JOINTS each
            side = moves[1][order]  # (E, n): the joint moves link b
            rank = np.where(side, np.cumsum(side, axis=1), np.cumsum(~side, axis=1))
            keep = rank <= SEPARATE_SIDE_JOINTS
            m = min(SEPARATE_CORNER_JOINTS, int(keep[0].sum()))
            chosen = np.take_along_axis(
                order, np.argsort(~keep, axis=1, kind="stable")[:, :m], axis=1
            )
        is_corner = np.zeros(half.shape, bool)
        np.put_along_axis(is_corner, chosen, True, axis=1)
        second = bounds[0][1] + bounds[1][1]
        split = np.where(is_corner, 0.5 * half * second, first)
        return chosen, np.sum(half * split, axis=1), split

    def has_separate_sides(self) -> bool:
        """Whether more free joints move the pair than one corner test takes and no free
        joint moves both links (``corner_plan``'s ``separate``)."""
        moves = self.moving_joints
        return len(self.names) > CORNER_JOINTS and not np.any(moves[0] & moves[1])

    @cached_property
    def moving_joints(self) -> tuple[np.ndarray, np.ndarray]:
        """Which free joints move each link (relative to the pair's common ancestor)."""
        out = []
        for side in self.sides:
            moves = np.zeros(len(self.names), bool)
            moves[[term.lead for term in side.terms]] = True
            out.append(moves)
        return out[0], out[1]

    def corner_bounds(
        self, lo: np.ndarray, hi: np.ndarray, chosen: np.ndarray, grown: np.ndarray, *,
        centres: tuple[np.ndarray, np.ndarray] | None = None, first: np.ndarray | None = None,
        settle: bool = True,
    ) -> np.ndarray:  # fmt: skip
        """Lower bounds on the links' distance over each box ``lo..hi`` from the hulls of their
        pieces' copies at the box's corners over the joints ``chosen`` (``corner_plan``).

        For each box, the ``C`` joints ``chosen`` take their two extreme values; the others, ``L``,
        stay at the centre ``c``. For a point ``p`` of a link and ``q`` in the box, ``|p(q_C, q_L) -
        p(q_C, c_L)| <= sum_{i in L} r_i h_i`` (the first-order bound, ``box_weights``). Over the
        ``C`` joints, the tensor-product linear interpolant ``I p`` of ``p`` between the ``2**|C|``
        corners is a convex combination of the corner values (its weights are products of ``t`` and
        ``1 - t``), and ``|p - I p| <= sum_{i in C} (h_i**2 / 2) sup |d2p/dq_i2|``: ``I = I_1 ...
        I_m`` telescopes, ``p - I p = sum_k I_1 ... I_{k-1} (p - I_k p)``, each linear interpolation
        is non-expanding in the sup norm, and one coordinate's error is at most ``(2 h)**2 / 8``
        times the second derivative's bound (for a vector ``g`` equal to its interpolant at both
        ends, apply the scalar bound to ``u . g`` with ``u`` the error's direction).
        ``kinematics.side_bounds`` bounds the derivatives over the whole box. So every point of a
        piece, carried rigidly with its link, lies within ``G = sum_{i in C} second_i h_i**2 / 2 +
        sum_{i in L} first_i h_i`` of the hull of the piece's copies at the corners (the piece is
        the hull of its vertices, and the ``G``-neighbourhood of a convex set is convex). Each link
        takes copies over the ``C`` joints that move it, and the bound is the least distance of the
        two links' hulls of copies, less both pads (``geometry.copied_distances``), less ``G_a +
        G_b``. Its error vanishes at the corners: per joint it is ``h_i / 2`` times the
        first-order term.

        The ``G`` of both links are ``grown``. With ``centres`` (the links' placements at the
        boxes' centres) and ``first`` (their first-order bounds plus the tolerance), a piece
        pair farther apart than ``first`` at the centre is clear of the tolerance over the box
        already and is not measured again. With ``settle``, only whether a bound exceeds the
        tolerance is known: a value at most the tolerance is not the least.
        """
        placed, counts = self.corner_placements(lo, hi, chosen)
        a, b = self.links[self.a], self.links[self.b]
        reach = grown + self.tolerance if settle else np.full(len(lo), np.inf)
        lowest, work = copied_distances(
            a.pack, b.pack, placed[0], counts[0], placed[1], counts[1], reach, a.pad, b.pad,
            centres=centres, first=first, settle=settle,
        )  # fmt: skip
        self.work += work
        return lowest - grown

    def corner_placements(self, lo: np.ndarray, hi: np.ndarray, chosen: np.ndarray):
        """Each link's placements at the corners of the boxes ``lo..hi`` over the joints
        ``chosen`` (``corner_bounds``) that move it, and how many there are:
        ``([(E, K, 4, 4), (E, K, 4, 4)], [(E,), (E,)])``. The corners that differ only in
        joints not moving a link place it alike, so each link is placed at its own corners
        only (the others are identity, past its count)."""
        count, m = len(lo), chosen.shape[1]
        centre = 0.5 * (lo + hi)
        bits = (np.arange(2**m)[:, None] >> np.arange(m)[None, :]) & 1 == 1  # (K, m)
        placed, counts = [], []
        for k, moves in enumerate(self.moving_joints):
            mask = moves[chosen]  # (E, m): the corner joints that move this side
            own = ~np.any(bits[None] & ~mask[:, None, :], axis=2)  # (E, K): its corners
            rows, corner = np.nonzero(own)  # each box's own corners, in order
            values = centre[rows]
            cols = chosen[rows]
            values[np.arange(len(rows))[:, None], cols] = np.where(
                bits[corner], hi[rows[:, None], cols], lo[rows[:, None], cols]
            )
            per_box = own.sum(axis=1)
            out = np.broadcast_to(np.eye(4), (count, int(per_box.max()), 4, 4)).copy()
            out[rows, np.cumsum(own, axis=1)[own] - 1] = self.side_placements(values, k)
            placed.append(out)
            counts.append(per_box)
        return placed, counts

    @cached_property
    def triangle_reach(self) -> float:
        """The largest first-order bound (plus the tolerance) of a box given the triangles'
        corner test: ``TRIANGLE_CORNER_REACH`` of the larger link's size (-inf when the pair
        has no triangles at its poses, ``fine`` off)."""
        if not self.fine:
            return -np.inf
        a, b = self.links[self.a], self.links[self.b]
        size = max(np.ptp(a.points, axis=0).max(), np.ptp(b.points, axis=0).max())
        return TRIANGLE_CORNER_REACH * float(size)

    def triangle_corner_bounds(
        self, lo: np.ndarray, hi: np.ndarray, chosen: np.ndarray, grown: np.ndarray,
        ta: np.ndarray, tb: np.ndarray, first: np.ndarray, allowance: float = np.inf,
    ) -> tuple[np.ndarray, int]:  # fmt: skip
        """``corner_bounds`` of the boxes ``lo..hi`` on the real meshes' triangles, for boxes
        whose convex pieces overlap: each triangle stands for itself, as a piece does there.
        In each box, triangle pairs farther apart than ``first`` (the box's first-order bound
        plus the tolerance) at the centre placements ``ta``, ``tb`` are clear over the box
        already; the others' copies at the corners are measured
        (``geometry.copied_distances``), and the least of their distances, less ``grown``,
        bounds the links' distance over the box. A value at most the tolerance is not the
        least; -inf for a box pairing more than ``MAX_TRIANGLE_PAIRS`` triangles (split it
        instead: its halves pair fewer) and for the boxes left once the work passes
        ``allowance`` (checked between boxes). Returns the bounds and how many boxes were
        measured."""
        out = np.full(len(lo), -np.inf)
        if len(lo) == 0:
            return out, 0
        a, b = self.links[self.a], self.links[self.b]
        placed, counts = self.corner_placements(lo, hi, chosen)
        measured = 0
        for e in range(len(lo)):
            if self.work > allowance:
                break
            measured += 1
            relative = np.linalg.solve(ta[e], tb[e])
            if not np.all(np.isfinite(relative)):
                continue
            self.work += (len(a.faces) + len(b.faces)) // 64
            pairs = near_triangle_pairs(
                a.vertices, a.faces, b.vertices, b.faces, relative, first[e]
            )
            self.work += len(pairs)
            if len(pairs) == 0:
                out[e] = np.inf
                continue
            if len(pairs) > MAX_TRIANGLE_PAIRS:
                continue
            packs = []
            for link, rows in ((a, pairs[:, 0]), (b, pairs[:, 1])):
                used = np.zeros(len(link.faces), bool)
                used[rows] = True
                packs.append(triangle_pack(link.vertices, link.faces[used]))
            lowest, work = copied_distances(
                packs[0], packs[1], placed[0][e : e + 1], counts[0][e : e + 1],
                placed[1][e : e + 1], counts[1][e : e + 1], grown[e : e + 1] + self.tolerance,
                np.zeros(len(packs[0].starts) - 1), np.zeros(len(packs[1].starts) - 1),
                settle=True,
            )  # fmt: skip
            self.work += work
            out[e] = float(lowest[0]) - grown[e]
        return out, measured

    def distances(
        self, ta: np.ndarray, tb: np.ndarray, reach: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Lower bounds on the distance between the two links' surfaces at placements ``ta``,
        ``tb``: from the coarse pieces (``piece_distances``), and where those come within
        ``reach`` and the reach is below ``FINE_REACH`` of the smaller link's size, the real
        meshes' exact distance (``surface_distance``: its cost grows with the triangle pairs
        within reach, so it waits for boxes small enough that it can close them); and the
        pieces' bounds alone."""
        a, b = self.links[self.a], self.links[self.b]
        work = [0]
        coarse = piece_distances(
            a.pack, b.pack, ta, tb, reach, a.pad, b.pad, settle=True, work=work
        )
        lowest = coarse.copy()
        fine = FINE_REACH * min(np.ptp(a.points, axis=0).max(), np.ptp(b.points, axis=0).max())
        fine = fine if self.fine else -np.inf
        for e in np.flatnonzero((lowest <= reach) & (reach <= fine)):
            if self.work + work[0] > self.allowance:
                break  # the pieces' bounds stand: lower, so nothing is certified wrongly
            lowest[e] = surface_distance(
                a, b, ta[e], tb[e], float(reach[e]), settle=True, work=work
            )
        self.work += work[0]
        return lowest, coarse

    def piece_distances(self, ta: np.ndarray, tb: np.ndarray, reach: float) -> np.ndarray:
        """The coarse pieces' signed distance bounds at placements ``ta``, ``tb`` (values above
        ``reach`` are bounds), their work counted."""
        a, b = self.links[self.a], self.links[self.b]
        work = [0]
        out = piece_distances(
            a.pack, b.pack, ta, tb, np.full(len(ta), reach), a.pad, b.pad, work=work
        )
        self.work += work[0]
        return out

    def verdict(self, ta: np.ndarray, tb: np.ndarray, *, surfaces_apart: bool = False) -> Verdict:
        """The real meshes' worst status at one placement of the two links."""
        worst = Verdict.CLEAR
        for i, offset_i in self.links[self.a].parts:
            mesh_a = self.bodies[i].mesh.copy().apply_transform(ta @ offset_i)
            for j, offset_j in self.links[self.b].parts:
                mesh_b = self.bodies[j].mesh.copy().apply_transform(tb @ offset_j)
                self.work += VERIFY_WORK + (len(mesh_a.faces) + len(mesh_b.faces)) // 64
                status = verify_pair(
                    mesh_a,
                    mesh_b,
                    tolerance=self.tolerance,
                    clearance=None,
                    surfaces_apart=surfaces_apart,
                ).status
                if status == Verdict.INTERFERENCE:
                    return status
                if status == Verdict.TOUCHING:
                    worst = Verdict.TOUCHING
        return worst

    def outcome(
        self,
        status: SweepStatus,
        boxes: int,
        witness: dict[str, float] | None = None,
        verdict: Verdict | None = None,
    ) -> PairSweep:
        """The pair's ``PairSweep``."""
        return PairSweep(self.a, self.b, status, tuple(self.names), witness, verdict, boxes)

    def witness_at(self, ta, tb, poses: dict, e: int, boxes: int) -> PairSweep | None:
        """``SOMETIMES`` with placement ``e`` of ``ta``, ``tb`` as the witness when the real
        meshes collide there, else None."""
        status = self.verdict(ta[e], tb[e])
        if status not in COLLIDING:
            return None
        witness = {n: float(poses[n][e]) for n in self.names}
        return self.outcome(SweepStatus.SOMETIMES, boxes, witness, status)


class WorkBudget:
    """The work a run's sweep may still do.

    Work counts what a link pair's search asks for (``LinkPair.work``): each pose costs the
    joints that move the pair (at least 1), each convex-piece pair measured by GJK 1 (and every
    64 piece boxes compared 1), each triangle pair measured 1, a check on the real meshes
    ``VERIFY_WORK`` and its triangles over 64, an envelope each point it turns
    (``envelope_pair``); every link pair visited costs at least
    ``PAIR_WORK``. Pairs are visited one after another in a fixed order and each may spend what
    is left, so which pairs are decided is a function of the inputs and the budget, never of
    time. A pair still searching when the budget is spent (checked after each batch of boxes)
    is undecided, and the pairs after it are left unswept, undecided too: never proven apart.

    Parameters
    ----------
    limit : int
        The work in all (``motion.Motion.budget``).

    Examples
    --------
    >>> budget = WorkBudget(10_000)
    >>> budget.charge(5_000)
    >>> budget.allowance, budget.pairs_left
    (5000, 2)
    >>> budget.charge(10)  # a pair costs at least PAIR_WORK
    >>> budget.allowance, budget.pairs_left
    (904, 1)
    >>> budget.charge(5_000)
    >>> budget.allowance is None  # spent: the next pair is not started
    True
    """

    def __init__(self, limit: int):
        self.limit, self.used, self.unswept = int(limit), 0, 0

    @property
    def allowance(self) -> int | None:
        """The work the next link pair may do, None when nothing is left."""
        left = self.limit - self.used
        return left if left > 0 else None

    @property
    def pairs_left(self) -> int:
        """A bound on the link pairs still to be visited (each costs ``PAIR_WORK`` or more)."""
        return self.pairs_within(PAIR_WORK)

    def pairs_within(self, least: int) -> int:
        """A bound on the link pairs still to be visited when each costs ``least`` or more."""
        return max(self.limit - self.used, 0) // least + 1

    def charge(self, work: int, *, least: int = PAIR_WORK) -> None:
        """Count a visited link pair's work (at least ``least``)."""
        self.used += max(int(work), least)


def chain_poses(
    robot: Robot, base: dict, names: list[str], values: np.ndarray, chains
) -> dict[str, np.ndarray]:
    """The values, ``{name: (E,) float64}``, of the free joints ``names`` (the rows of
    ``values``) and of every movable joint of ``chains``: free ones from ``values``, mimic
    joints following their leaders, the others at ``base``: only the joints that place the
    pair's links."""
    count = len(values)
    out = {name: values[:, k] for k, name in enumerate(names)}

    def value(joint: Joint) -> np.ndarray:
        if joint.name not in out:
            if joint.mimic is not None and robot.leader(joint)[0] in names:
                leader, multiplier, offset = joint.mimic
                out[joint.name] = multiplier * value(robot.joint(leader)) + offset
            else:
                out[joint.name] = np.full(count, base[joint.name])
        return out[joint.name]

    for chain in chains:
        for joint in chain:
            if joint.type in MOVABLE:
                value(joint)
    return out


def sweep_pair(
    pair: LinkPair,
    lower: np.ndarray,
    upper: np.ndarray,
    resolution: float,
    *,
    allowance: int | None = None,
) -> PairSweep:
    """Classify one link pair over the box ``lower..upper`` of its free joints.

    Boxes of joint values are evaluated at their centre ``c`` with half-widths ``h``: the
    pieces' distance there (or, for a box small enough, the real triangles', see
    ``LinkPair.distances``) bounds the links' surface distance from below, and no point moves by
    more than ``M = sum_k r_k h_k`` (``LinkPair.box_weights``: each joint's lever arm bounded
    at the box's centre pose) within the box, so a box whose centre distance exceeds
    ``M + tolerance`` is certified free of contact. Other boxes are halved along the joint that
    contributes most to ``M``, down to ``resolution``. Once a pair has evaluated
    ``CORNER_AFTER`` boxes, a box its centre does not certify gets the corner test
    (``LinkPair.corner_bounds``: the hulls of each link's pieces placed at the box's corners,
    less a second-order bound) and, when that fails too, is halved across the joint with the
    largest term of that bound; a box the pieces' corner test does not close, whose bound is
    small enough (``TRIANGLE_CORNER_REACH``), gets the same test on the real meshes' triangles
    (``LinkPair.triangle_corner_bounds``). Centres where pieces overlap are
    re-checked on the real meshes, nearest first: one that interferes or touches is the witness
    of ``sometimes``; after ``DESCENT_AFTER`` boxes, and each time they grow by
    ``DESCENT_GROWTH`` after that, a descent from the nearest centres so far looks for one
    (``descent_witness``). When every box is certified, the surfaces never come within
    the tolerance, so whether one link is buried in the other cannot change over the sweep: one
    exact check at the centre decides ``never`` (or ``always``, buried throughout). A pair
    still open after ``ENVELOPE_AFTER`` boxes tries to prove it over its links' envelopes
    instead, the revolute joints at the ends of their chains taken out of the search
    (``envelope_proof``). A pair that would evaluate more than ``MAX_BOXES`` (and the
    envelopes' ``ENVELOPE_BOXES``, and, for a pair no joint of which moves both links, a
    second search within ``SEPARATE_BOXES`` with corners over each link's own joints and
    envelopes within ``SEPARATE_ENVELOPE_BOXES``), or whose work (``LinkPair.work``) passes
    ``allowance`` (checked after each batch), is undecided.
    """
    allowance = np.inf if allowance is None else allowance
    pair.allowance = allowance
    if len(lower) == 0:  # nothing moves one link relative to the other
        return fixed_pair(pair)
    found = sampled_witness(pair, lower, upper)
    if found is not None:
        return found
    found = box_search(pair, lower, upper, resolution, allowance)
    if found.status != SweepStatus.UNDECIDED or not pair.has_separate_sides():
        return found
    # again with corners on both links' own joints: each copy costs more, so only for a pair
    # the first search could not decide (two arms, a head and an arm)
    again = box_search(
        pair, lower, upper, resolution, allowance, evaluated=0, witnesses=False,
        max_boxes=SEPARATE_BOXES, separate=True, envelope=True,
        envelope_boxes=SEPARATE_ENVELOPE_BOXES,
    )  # fmt: skip
    boxes = found.boxes + again.boxes
    return replace(again if again.status != SweepStatus.UNDECIDED else found, boxes=boxes)


def box_search(
    pair: LinkPair,
    lower: np.ndarray,
    upper: np.ndarray,
    resolution: float,
    allowance: float,
    *,
    evaluated: int = SAMPLES,
    witnesses: bool = True,
    max_boxes: int | None = None,
    separate: bool = False,
    envelope: bool | None = None,
    envelope_boxes: int | None = None,
) -> PairSweep:
    """``sweep_pair``'s search of the boxes, ``evaluated`` boxes counted already (an envelope's
    boxes are counted too, but apart from ``max_boxes`` and the descents' schedule). Without
    ``witnesses`` (an envelope's pair, ``envelope_proof``) it only proves: no pose is checked on
    the real meshes, and the first box centre where the pieces come within the tolerance, or
    box at the resolution, leaves the pair undecided. ``max_boxes`` defaults to ``MAX_BOXES``.
    ``separate`` takes each box's corners over each link's own joints (``corner_plan``);
    ``envelope`` (default: ``witnesses``) lets an open pair try its links' envelopes, within
    ``envelope_boxes`` (default ``ENVELOPE_BOXES``)."""
    max_boxes = MAX_BOXES if max_boxes is None else max_boxes
    envelope_boxes = ENVELOPE_BOXES if envelope_boxes is None else envelope_boxes
    lo, hi = lower[None, :].copy(), upper[None, :].copy()
    checks, unresolved, aside = 0, False, 0  # aside: the envelopes' boxes
    envelope = witnesses if envelope is None else envelope
    nearest, descents, enveloped = NearestCentres(DESCENT_STARTS), 0, not envelope
    while len(lo):
        if witnesses and evaluated - aside >= DESCENT_AFTER * DESCENT_GROWTH**descents:
            starts = nearest.values
            found = descent_witness(pair, lower, upper, starts, evaluated, seed=descents + 1)
            if found is not None:
                return found
            descents += 1
        if not enveloped and evaluated >= ENVELOPE_AFTER and nearest.values is not None:
            enveloped = True
            found, boxes = envelope_proof(
                pair, lower, upper, resolution, nearest, evaluated, separate=separate,
                max_boxes=envelope_boxes,
            )  # fmt: skip
            if found is not None:
                return found
            evaluated, aside = evaluated + boxes, boxes
        blo, bhi, lo, hi = lo[:BATCH], hi[:BATCH], lo[BATCH:], hi[BATCH:]
        centre, half = 0.5 * (blo + bhi), 0.5 * (bhi - blo)
        axes: dict = {}
        ta, tb, poses = pair.placements(centre, axes)
        rates = pair.joint_rates(ta, tb, axes, half)
        w = combined_weights(pair.sides, rates, half.shape)
        bound = np.sum(half * w, axis=1) + pair.tolerance
        lowest, coarse = pair.distances(ta, tb, bound)
        evaluated += len(centre)
        if not witnesses and np.any(lowest <= pair.tolerance):
            return pair.outcome(SweepStatus.UNDECIDED, evaluated)  # no proof can close that box
        nearest.add(lowest, centre)
        for e in np.argsort(lowest, kind="stable"):
            if lowest[e] > pair.tolerance or checks >= MAX_WITNESS_CHECKS:
                break
            checks += 1
            found = pair.witness_at(ta, tb, poses, e, evaluated)
            if found is not None:
                return found
        open_ = lowest <= bound
        if evaluated - aside > CORNER_AFTER and np.any(open_):
            rows = np.flatnonzero(open_)
            picked = ([r[rows] for r in rates[0]], [r[rows] for r in rates[1]])
            chosen, grown, split = pair.corner_plan(half[rows], picked, separate=separate)
            w = w.copy()
            w[rows] = split  # halve_boxes cuts across the largest term of the bound in force
            # the hulls come no farther apart than the pieces at the centre, give or take
            # the interpolation's error: boxes whose pieces' centre distance is not past it
            # (the real meshes' may be) are left to split
            hopeful = coarse[rows] > grown + pair.tolerance
            # where the pieces' corner test is not tried or fails, the triangles' may close
            # the box (their pieces overlap there, their real meshes need not); a box small
            # enough for the triangles' goes to it alone: each triangle lies in its piece, so
            # it closes every box the pieces' would (unless it pairs MAX_TRIANGLE_PAIRS)
            near = pair.triangle_reach
            fine_rows, fine_chosen, fine_grown = rows, chosen, grown
            hopeful &= bound[rows] > near
            rows, chosen, grown = rows[hopeful], chosen[hopeful], grown[hopeful]
            for k in range(0, len(rows), CORNER_BATCH):  # the work checked between batches
                if pair.work > allowance:
                    break  # the boxes left stay open: the pair stops after this batch
                part = slice(k, k + CORNER_BATCH)
                some = rows[part]
                corner = pair.corner_bounds(
                    blo[some], bhi[some], chosen[part], grown[part],
                    centres=(ta[some], tb[some]), first=bound[some],
                )  # fmt: skip
                open_[some[corner > pair.tolerance]] = False
                evaluated += CORNER_BOXES * len(some)
            # (a box whose triangles meet at its centre: no corner test can close it)
            pick = open_[fine_rows] & (bound[fine_rows] <= near)
            pick &= ~(
                (coarse[fine_rows] < lowest[fine_rows]) & (lowest[fine_rows] <= pair.tolerance)
            )
            if np.any(pick) and pair.work <= allowance:
                some = fine_rows[pick]
                corner, measured = pair.triangle_corner_bounds(
                    blo[some], bhi[some], fine_chosen[pick], fine_grown[pick], ta[some],
                    tb[some], bound[some], allowance,
                )  # fmt: skip
                open_[some[corner > pair.tolerance]] = False
                evaluated += CORNER_BOXES * measured
        if not np.any(open_):
            continue
        blo, bhi, half, w = blo[open_], bhi[open_], half[open_], w[open_]
        splittable = np.any(2.0 * half > resolution, axis=1)
        if not witnesses and not np.all(splittable):
            return pair.outcome(SweepStatus.UNDECIDED, evaluated)
        for e in np.flatnonzero(~splittable)[: max(0, MAX_WITNESS_CHECKS - checks) // 2]:
            unresolved = True  # at the resolution: its corners may still collide
            checks += 2
            found = first_witness(pair, np.stack([blo[e], bhi[e]]), evaluated)
            if found is not None:
                return found
        unresolved |= bool(np.any(~splittable))
        new_lo, new_hi = halve_boxes(blo[splittable], bhi[splittable], w[splittable])
        lo, hi = np.concatenate([lo, new_lo]), np.concatenate([hi, new_hi])
        if evaluated - aside + len(lo) > max_boxes or pair.work > allowance:
            return pair.outcome(SweepStatus.UNDECIDED, evaluated)
    if unresolved:
        return pair.outcome(SweepStatus.UNDECIDED, evaluated)
    ta, tb, _ = pair.placements(0.5 * (lower + upper)[None, :])
    buried = pair.verdict(ta[0], tb[0], surfaces_apart=True) == Verdict.INTERFERENCE
    return pair.outcome(SweepStatus.ALWAYS if buried else SweepStatus.NEVER, evaluated)


def envelope_proof(
    pair: LinkPair, lower, upper, resolution: float, nearest: NearestCentres, evaluated: int,
    *, separate: bool = False, max_boxes: int | None = None,
) -> tuple[PairSweep | None, int]:  # fmt: skip
    """Never (or always) proven over the envelopes of the links' last joints
    (``envelope_pair``), within ``max_boxes`` in all (default ``ENVELOPE_BOXES``), else None;
    and the boxes it evaluated.

    The envelopes may first reach as far beyond the links as ``ENVELOPE_SHARE`` of the
    smallest distance at the box centres so far less the tolerance (a pair that comes close
    somewhere keeps the joints that bring it there); when their search fails, with half that,
    and so on, each time other joints go."""
    max_boxes = ENVELOPE_BOXES if max_boxes is None else max_boxes
    margin = ENVELOPE_SHARE * max(float(nearest.lowest.min()) - pair.tolerance, 0.0)
    boxes, kept = 0, None
    while boxes < max_boxes and margin > 0.0:
        made = envelope_pair(pair, lower, upper, margin)
        if made is None:
            break
        if made[0].names == kept:  # the same joints went: tried already
            margin *= 0.5
            continue
        sub, sub_lower, sub_upper = made
        kept = sub.names
        found = box_search(
            sub, sub_lower, sub_upper, resolution, pair.allowance - pair.work, evaluated=0,
            witnesses=False, max_boxes=max_boxes - boxes, separate=separate,
        )  # fmt: skip
        pair.work += sub.work
        boxes += found.boxes
        if found.status in (SweepStatus.NEVER, SweepStatus.ALWAYS):
            return pair.outcome(found.status, evaluated + boxes), boxes
        margin *= 0.5
    return None, boxes


def envelope_pair(
    pair: LinkPair, lower: np.ndarray, upper: np.ndarray, margin: float
) -> tuple[LinkPair, np.ndarray, np.ndarray] | None:
    """The pair with the revolute joints at the ends of its links' chains taken out of the
    search: each link replaced by its envelope over the joint's range (``envelope.envelope``),
    the joint held at its range's middle. Joints go one at a time, from the links up, the one
    whose envelope reaches least beyond its link first, while the envelopes' reaches sum to at
    most ``margin``; a joint that leads another of the pair's joints (a mimic) stays. None when
    no joint goes.

    Returns
    -------
    (LinkPair, (n',) float64, (n',) float64)
        The pair over the joints left (no real-mesh distances: ``LinkPair.fine`` off) and their
        ranges.
    """
    robot = pair.robot
    links, base = dict(pair.links), dict(pair.base)
    names, lo, hi = list(pair.names), list(lower), list(upper)
    leads = Counter(term.lead for side in pair.sides for term in side.terms)
    ends = [list(side.terms) for side in pair.sides]  # from the common ancestor down
    gone: list[tuple[str, ...]] = [(), ()]
    spent = 0.0
    while True:
        options = []
        for k, terms in enumerate(ends):
            if not terms:
                continue
            joint, term = terms[-1].joint, terms[-1]
            if (
                joint.type not in ROTARY
                or leads[term.lead] != 1
                or robot.leader(joint) != (joint.name, 1.0)
            ):
                continue
            link = pair.sides[k].link
            key = (link, *gone[k], joint.name)  # the same envelope in any of the robot's pairs
            if key not in pair.envelopes:
                i = names.index(joint.name)
                origin, direction = axis_in_link(pair, k, joint.name, base)
                pair.envelopes[key] = envelope(links[link], origin, direction, lo[i], hi[i])
                # its cost grows with the points turned (about a million a second)
                pair.work += len(links[link].pack.points) * (steps(hi[i] - lo[i]) + 1)
            options.append((pair.envelopes[key][1], k, joint.name, key))
        if not options:
            break
        reach, k, name, key = min(options)
        if spent + reach > margin:
            break
        spent += reach
        ends[k].pop()
        gone[k] = key[1:]
        links[pair.sides[k].link] = pair.envelopes[key][0]
        i = names.index(name)
        base[name] = 0.5 * (lo[i] + hi[i])
        del names[i], lo[i], hi[i]
    if len(names) == len(pair.names):
        return None
    sides = link_sides(robot, (pair.a, pair.b), links, names, set(names), base, pair.scale)
    sub = LinkPair(
        robot, pair.a, pair.b, names, sides, base, pair.scale, pair.tolerance, links,
        pair.bodies, fine=False, envelopes=pair.envelopes,
    )  # fmt: skip
    return sub, np.array(lo), np.array(hi)


def axis_in_link(pair: LinkPair, k: int, name: str, base: dict) -> tuple[np.ndarray, np.ndarray]:
    """(point, unit direction) of joint ``name``'s axis line in the frame of the pair's link
    ``k`` (0: ``a``), at the joint values ``base``."""
    chain = pair.chains[k]
    poses = {j.name: np.array([base[j.name]]) for j in chain if j.type in MOVABLE}
    axes: dict = {}
    placed = chain_transforms(pair.folded[k], poses, pair.scale, 1, axes)[0]
    point, direction = axes[name]
    inverse = np.linalg.inv(placed)
    return inverse[:3, :3] @ point[0] + inverse[:3, 3], placed[:3, :3].T @ direction[0]


def fixed_pair(pair: LinkPair) -> PairSweep:
    """A pair no swept joint moves relative to each other: ``ALWAYS`` (with an empty witness)
    when the real meshes collide at the run's pose, else ``NEVER``."""
    ta, tb, _ = pair.placements(np.zeros((1, 0)))
    verdict = pair.verdict(ta[0], tb[0])
    if verdict in COLLIDING:
        return pair.outcome(SweepStatus.ALWAYS, 1, {}, verdict)
    return pair.outcome(SweepStatus.NEVER, 1)


def halve_boxes(lo: np.ndarray, hi: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each box ``lo..hi`` cut in two across the joint contributing most to its motion bound
    (``w``: (E, n) each box's bound per unit of each joint)."""
    axis = np.argmax(0.5 * (hi - lo) * w, axis=1)
    rows = np.arange(len(axis))
    mid = 0.5 * (lo[rows, axis] + hi[rows, axis])
    left_hi, right_lo = hi.copy(), lo.copy()
    left_hi[rows, axis], right_lo[rows, axis] = mid, mid
    return np.concatenate([lo, right_lo]), np.concatenate([left_hi, hi])


class NearestCentres:
    """The ``count`` box centres whose links came nearest so far (ties: the earlier)."""

    def __init__(self, count: int):
        self.count, self.lowest, self.values = count, np.empty(0), None

    def add(self, lowest: np.ndarray, values: np.ndarray) -> None:
        both = np.concatenate([self.lowest, lowest])
        rows = values if self.values is None else np.concatenate([self.values, values])
        keep = np.argsort(both, kind="stable")[: self.count]
        self.lowest, self.values = both[keep], rows[keep]


def descent_witness(
    pair: LinkPair, lower, upper, starts, boxes: int, *, seed: int = 1
) -> PairSweep | None:
    """A witness near the box centres where the links came nearest (``starts``): each is
    moved, ``DESCENT_STEPS`` times, to the nearest of ``DESCENT_TRIES`` perturbations of it
    (fixed seed; each joint's step in proportion to its range, halved when none comes nearer)
    by the coarse pieces' signed distance; the final poses whose pieces overlap are
    re-checked on the real meshes, nearest first. A pair colliding only in a narrow window
    of many joints is found in a few thousand poses instead of by splitting boxes down to it.
    ``seed`` draws the perturbations: each later descent of a pair draws its own. After
    ``DESCENT_SETTLE`` steps it stops as soon as some pose's pieces overlap, or every start's
    step has shrunk to ``1 / DESCENT_SETTLED`` of its first: the steps after that are for
    starts still moving toward a collision.
    """
    if starts is None or len(starts) == 0:
        return None
    rng = np.random.default_rng(seed)

    def measure(values, reach: float):
        ta, tb, _ = pair.placements(values)
        return pair.piece_distances(ta, tb, reach)

    current = starts.copy()
    scores = measure(current, np.inf)
    reach = max(float(scores.max()), 0.0) + pair.tolerance  # nothing beyond the starts matters
    first = 0.125 * (upper - lower)
    step = np.broadcast_to(first, current.shape).copy()
    for k in range(DESCENT_STEPS):
        if k >= DESCENT_SETTLE and (
            np.any(scores <= pair.tolerance) or np.all(step <= first / DESCENT_SETTLED)
        ):
            break
        better = descent_step(
            lambda values: measure(values, reach), lower, upper, current, scores, step, rng,
            DESCENT_TRIES,
        )  # fmt: skip
        step[~better] *= 0.5
    order = np.argsort(scores, kind="stable")
    order = order[scores[order] <= pair.tolerance][:SAMPLE_CHECKS]
    return first_witness(pair, current[order], boxes)


def descent_step(
    measure, lower, upper, current: np.ndarray, scores: np.ndarray, step: np.ndarray, rng,
    tries: int,
) -> np.ndarray:  # fmt: skip
    """One step of a descent: each row of ``current`` (joint values, (k, n)) moves to the
    nearest, by ``measure`` ((m, n) values -> (m,) distances), of ``tries`` normal
    perturbations of it scaled by its row of ``step`` and clipped to ``lower..upper``, when
    that is below its ``scores``. ``current`` and ``scores`` are updated in place; returns
    which rows moved."""
    noise = rng.standard_normal((len(current), tries, len(lower)))
    moved = np.clip(current[:, None, :] + step[:, None, :] * noise, lower, upper)
    found = measure(moved.reshape(-1, len(lower))).reshape(len(current), tries)
    best = np.argmin(found, axis=1)
    better = found[np.arange(len(current)), best] < scores
    current[better] = moved[better, best[better]]
    scores[better] = found[better, best[better]]
    return better


def sampled_witness(pair: LinkPair, lower: np.ndarray, upper: np.ndarray) -> PairSweep | None:
    """A witness among ``SAMPLES`` poses drawn with a fixed seed (most pairs that collide do so
    over a wide region, found here before any box is split), else None."""
    rng = np.random.default_rng(0)
    values = lower + (upper - lower) * rng.random((SAMPLES, len(lower)))
    ta, tb, _ = pair.placements(values)
    lowest, _ = pair.distances(ta, tb, np.full(SAMPLES, pair.tolerance))
    order = np.argsort(lowest, kind="stable")[:SAMPLE_CHECKS]
    return first_witness(pair, values[order[lowest[order] <= pair.tolerance]], SAMPLES)


def first_witness(pair: LinkPair, values: np.ndarray, boxes: int) -> PairSweep | None:
    """The first of ``values`` (free joints' values, (k, n)) where the real meshes collide."""
    if len(values) == 0:
        return None
    ta, tb, poses = pair.placements(values)
    for e in range(len(values)):
        found = pair.witness_at(ta, tb, poses, e, boxes)
        if found is not None:
            return found
    return None
