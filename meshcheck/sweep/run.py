"""The sweep stage: every robot of the run (``load.Assembly.mechanisms``), each link pair
classified never / sometimes / always / undecided over the swept joints' ranges."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..decompose import decompose_bodies
from ..load import Body
from ..load.robot import Mechanism
from ..progress import Progress
from ..results import PairSweep, RobotSweep
from ..tolerances import pair_tolerances, part_sizes
from ..units import scale as unit_scale
from .distances import link_geometries
from .kinematics import frame_reach, joint_ranges, link_sides, motion_weights
from .mechanisms import (
    audited_pairs,
    check_swept,
    links_within,
    pair_count,
    pairs_in_order,
    swept_joints,
    with_approval_reasons,
)
from .search import PAIR_WORK, SKIP_WORK, LinkPair, WorkBudget, sweep_pair


def sweep_mechanism(
    mech: Mechanism,
    bodies: Sequence[Body],
    pieces: dict[int, list[np.ndarray]],
    motion,
    *,
    tolerance: float | None = None,
    budget: WorkBudget | None = None,
    pairs: set[frozenset[str]] | None = None,
) -> tuple[PairSweep, ...]:
    """Classify every pair of a robot's links over the swept joints' ranges (``sweep_pair``),
    or only ``pairs``, as far as the work budget goes.

    Parameters
    ----------
    mech : Mechanism
    bodies : sequence of Body
        The run's parts, placed at ``motion.pose``.
    pieces : dict of int -> list of (n_i, 3) float64
        Convex pieces of each of the robot's parts, world coordinates at that pose, covering
        every triangle (``mechanism_pieces``).
    motion : motion.Motion
        The pose (held joints stay there), the joints swept (``()``: every movable one), the
        resolution and the budget.
    tolerance : float, optional
        Touching tolerance, report units; default each pair's own (``tolerances.pair_tolerances``).
    budget : WorkBudget, optional
        The run's (default one of ``motion.budget`` for this robot alone). Pairs are swept in
        ``pairs_in_order``; those it cannot pay for are counted in ``budget.unswept``.
    pairs : set of frozenset of str, optional
        Sweep only these link pairs (an SRDF's, ``sweep.audit``): only their links need
        ``pieces``, and each pair's tolerance is the rule's over those links.

    Returns
    -------
    tuple of PairSweep
        One per pair of links with collision geometry (of ``pairs``) that was swept, sorted by
        link names.
    """
    if pairs is not None:
        named = {link for pair in pairs for link in pair}
        mech = dataclasses.replace(mech, parts={k: v for k, v in mech.parts.items() if k in named})
        if not mech.parts:
            return ()
    robot = mech.robot
    budget = WorkBudget(motion.budget) if budget is None else budget
    base = mech.pose  # every movable joint's value at the run's pose, this mechanism's own
    swept = swept_joints(robot, motion.sweep)
    scale = unit_scale(mech.units, bodies[mech.parts[next(iter(mech.parts))][0]].units)
    order = links_within(mech, budget.pairs_within(least_work(mech)), pairs)
    links = link_geometries(robot, mech, bodies, pieces, base, scale, only=set(order))
    radius = {name: link.radius for name, link in links.items()}
    points = {name: link.points for name, link in links.items()}
    names = sorted(links)
    index = {n: k for k, n in enumerate(names)}
    lower = np.array([links[n].points.min(axis=0) for n in names])
    upper = np.array([links[n].points.max(axis=0) for n in names])
    diagonal, _ = part_sizes(lower, upper)
    magnitude = np.full(len(names), max(radius.values()) + frame_reach(robot, swept, base) * scale)
    total = pair_count(mech, pairs)
    out, done, current, envelopes = [], 0, (), {}
    with Progress("sweeping link pairs", total, detail=lambda: " / ".join(current)) as progress:
        for current in pairs_in_order(order, pairs):
            a, b = current
            tol = tolerance
            if tol is None:
                tol = float(
                    pair_tolerances(diagonal, magnitude, np.array([[index[a], index[b]]]))[0]
                )
            allowance = budget.allowance
            if allowance is None:
                break
            done += 1
            progress.update(done)
            weights = motion_weights(robot, (a, b), radius, swept, base, scale, points)
            if not weights and not mech.is_urdf:
                budget.charge(SKIP_WORK, least=SKIP_WORK)
                continue  # nothing moves them: the check judged them at the pose
            free = sorted(weights)
            sides = link_sides(robot, (a, b), links, free, swept, base, scale)
            pair = LinkPair(
                robot, a, b, free, sides, base, scale, tol, links, bodies, envelopes=envelopes
            )
            lo, hi = joint_ranges(robot, free)
            swept_pair = sweep_pair(pair, lo, hi, motion.resolution, allowance=allowance)
            budget.charge(pair.work)
            is_adjacent = frozenset((a, b)) in mech.adjacent
            out.append(dataclasses.replace(swept_pair, is_adjacent=is_adjacent))
        budget.unswept += total - done
        if total > done:
            progress.note(
                f"the sweep budget ({budget.limit:,}) ran out: "
                f"{total - done:,} link pairs of {robot.name or 'a robot'} left undecided"
            )
        progress.close(is_complete=total == done)
    return tuple(sorted(out, key=lambda p: (p.a, p.b)))


def least_work(mech: Mechanism) -> int:
    """The least work a link pair of ``mech`` costs: a URDF robot sweeps every pair
    (``search.PAIR_WORK``); a ``[[joint]]`` mechanism passes over the pairs no swept joint
    moves (``search.SKIP_WORK``)."""
    return PAIR_WORK if mech.is_urdf else SKIP_WORK


def mechanism_pieces(
    bodies: Sequence[Body],
    mechanisms: Sequence[Mechanism],
    settings,
    *,
    executor=None,
    cache=None,
) -> dict[int, list[np.ndarray]]:
    """Convex pieces of the parts of the mechanisms a ``--sweep`` poses, by body index; without
    ``--sweep``, of the links an audited SRDF's pairs name (``sweep.audit``), else ``{}``; in
    both, only of the links the work budget can reach (``links_within``). A ``--sweep-joints``
    name no mechanism has is refused first. CoACD runs on ``executor``; pieces are kept in
    ``cache``, the run's decompositions.

    Each part is CoACD's decomposition, never a stand-in hull: no time limit (a time-out would
    swap a link's pieces for its hull, and the sweep's classes, the SRDF, would then depend on
    how the run went), whatever the check's cost model says. The check uses these pieces for
    the parts it needs (``pipeline.decompose_parts``), so no part is decomposed twice.
    """
    if settings.motion.sweep is None and not any(m.srdf is not None for m in mechanisms):
        return {}
    check_swept(mechanisms, settings.motion.sweep)
    out: dict[int, list[np.ndarray]] = {}
    budget = WorkBudget(settings.motion.budget)
    for mech in mechanisms:
        wanted = None
        if settings.motion.sweep is None:
            if mech.srdf is None:
                continue
            wanted = audited_pairs(mech.srdf, settings.motion)
            named = {link for pair in wanted for link in pair}
            mech = dataclasses.replace(
                mech, parts={k: v for k, v in mech.parts.items() if k in named}
            )
        reach = budget.pairs_within(least_work(mech))
        ks = sorted(k for link in links_within(mech, reach, wanted) for k in mech.parts[link])
        piece_lists = decompose_bodies(
            [bodies[k] for k in ks],
            threshold=settings.threshold,
            cache=cache,
            jobs=settings.jobs,
            executor=executor,
            time_limit=None,
        )
        out.update(zip(ks, piece_lists, strict=True))
    return out


def sweep_bodies(
    bodies: Sequence[Body],
    mechanisms: Sequence[Mechanism],
    settings,
    *,
    pieces: dict[int, list[np.ndarray]] | None = None,
    executor=None,
) -> tuple[RobotSweep, ...]:
    """``sweep_mechanism`` of every robot among ``bodies`` when ``settings.motion.sweep`` is
    set (else ``()``), each ``[[joint]]`` pair with the reason of the approval its parts match.

    Parameters
    ----------
    bodies : sequence of Body
    mechanisms : sequence of Mechanism
        ``load.Assembly.mechanisms``.
    settings : Settings
    pieces : dict of int -> list of (n_i, 3) float64, optional
        ``mechanism_pieces``, when the caller has them; default: decomposed here.
    executor : execute.Executor, optional
        Where CoACD runs when the pieces are decomposed here.
    """
    if settings.motion.sweep is None:
        return ()
    if pieces is None:
        pieces = mechanism_pieces(bodies, mechanisms, settings, executor=executor)
    out = []
    budget = WorkBudget(settings.motion.budget)  # one for the run, robot after robot
    for mech in mechanisms:
        used, unswept = budget.used, budget.unswept
        pairs = sweep_mechanism(
            mech, bodies, pieces, settings.motion, tolerance=settings.tolerance, budget=budget
        )
        out.append(
            RobotSweep(
                mech.robot.path,
                mech.robot.name,
                pairs,
                mech.is_urdf,
                unswept=budget.unswept - unswept,
                work=budget.used - used,
                budget=budget.limit,
            )
        )
    return with_approval_reasons(out, bodies, settings.approvals)
