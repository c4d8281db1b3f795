"""The sweep stage: every robot of the run (``load.Assembly.mechanisms``), each link pair
classified never / sometimes / always / undecided over the swept joints' ranges."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..decompose import decompose_bodies
from ..load import Body
from ..load.robot import Mechanism, joint_values
from ..results import PairSweep, RobotSweep
from ..tolerances import pair_tolerances, part_sizes
from ..units import scale as unit_scale
from .distances import link_geometries
from .kinematics import frame_reach, joint_ranges, link_sides, motion_weights
from .mechanisms import audited_pairs, check_swept, swept_joints, with_approval_reasons
from .search import LinkPair, sweep_pair


def sweep_mechanism(
    mech: Mechanism,
    bodies: Sequence[Body],
    pieces: dict[int, list[np.ndarray]],
    motion,
    *,
    tolerance: float | None = None,
    pairs: set[frozenset[str]] | None = None,
) -> tuple[PairSweep, ...]:
    """Classify every pair of a robot's links over the swept joints' ranges (``sweep_pair``),
    or only ``pairs``.

    Parameters
    ----------
    mech : Mechanism
    bodies : sequence of Body
        The run's parts, placed at ``motion.pose``.
    pieces : dict of int -> list of (n_i, 3) float64
        Convex pieces of each of the robot's parts, world coordinates at that pose, covering
        every triangle (``mechanism_pieces``).
    motion : motion.Motion
        The pose (held joints stay there), the joints swept (``()``: every movable one) and the
        resolution.
    tolerance : float, optional
        Touching tolerance, report units; default each pair's own (``tolerances.pair_tolerances``).
    pairs : set of frozenset of str, optional
        Sweep only these link pairs (an SRDF's, ``sweep.audit``): only their links need
        ``pieces``, and each pair's tolerance is the rule's over those links.

    Returns
    -------
    tuple of PairSweep
        One per pair of links with collision geometry (of ``pairs``), sorted by link names.
    """
    if pairs is not None:
        named = {link for pair in pairs for link in pair}
        mech = dataclasses.replace(mech, parts={k: v for k, v in mech.parts.items() if k in named})
        if not mech.parts:
            return ()
    robot = mech.robot
    base = joint_values(robot, motion.pose)
    swept = swept_joints(robot, motion.sweep)
    scale = unit_scale(mech.units, bodies[mech.parts[next(iter(mech.parts))][0]].units)
    links = link_geometries(robot, mech, bodies, pieces, base, scale)
    radius = {name: link.radius for name, link in links.items()}
    points = {name: link.points for name, link in links.items()}
    names = sorted(links)
    lower = np.array([links[n].points.min(axis=0) for n in names])
    upper = np.array([links[n].points.max(axis=0) for n in names])
    diagonal, _ = part_sizes(lower, upper)
    magnitude = np.full(len(names), max(radius.values()) + frame_reach(robot, swept, base) * scale)
    out = []
    for x, a in enumerate(names):
        for y in range(x + 1, len(names)):
            b = names[y]
            if pairs is not None and frozenset((a, b)) not in pairs:
                continue
            tol = tolerance
            if tol is None:
                tol = float(pair_tolerances(diagonal, magnitude, np.array([[x, y]]))[0])
            weights = motion_weights(robot, (a, b), radius, swept, base, scale, points)
            if not weights and not mech.is_urdf:
                continue  # nothing moves them: the check judged them at the pose
            free = sorted(weights)
            sides = link_sides(robot, (a, b), links, free, swept, base, scale)
            pair = LinkPair(robot, a, b, free, sides, base, scale, tol, links, bodies)
            lo, hi = joint_ranges(robot, free)
            swept_pair = sweep_pair(pair, lo, hi, motion.resolution)
            is_adjacent = frozenset((a, b)) in mech.adjacent
            out.append(dataclasses.replace(swept_pair, is_adjacent=is_adjacent))
    return tuple(out)


def mechanism_pieces(
    bodies: Sequence[Body],
    mechanisms: Sequence[Mechanism],
    settings,
    *,
    executor=None,
    cache=None,
) -> dict[int, list[np.ndarray]]:
    """Convex pieces of every part of the mechanisms a ``--sweep`` poses, by body index; without
    ``--sweep``, of the links an audited SRDF's pairs name (``sweep.audit``), else ``{}``. A
    ``--sweep-joints`` name no mechanism has is refused first. CoACD runs on ``executor``;
    pieces are kept in ``cache``, the run's decompositions.

    Each part is CoACD's decomposition, never a stand-in hull: no time limit (a time-out would
    swap a link's pieces for its hull, and the sweep's classes, the SRDF, would then depend on
    how the run went), whatever the check's cost model says. The check uses these pieces for
    the parts it needs (``pipeline.decompose_parts``), so no part is decomposed twice.
    """
    if settings.motion.sweep is None and not any(m.srdf is not None for m in mechanisms):
        return {}
    check_swept(mechanisms, settings.motion.sweep)
    out: dict[int, list[np.ndarray]] = {}
    for mech in mechanisms:
        if settings.motion.sweep is None:
            if mech.srdf is None:
                continue
            named = {link for pair in audited_pairs(mech.srdf, settings.motion) for link in pair}
            mech = dataclasses.replace(
                mech, parts={k: v for k, v in mech.parts.items() if k in named}
            )
        ks = sorted(k for ks in mech.parts.values() for k in ks)
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
    for mech in mechanisms:
        pairs = sweep_mechanism(mech, bodies, pieces, settings.motion, tolerance=settings.tolerance)
        out.append(RobotSweep(mech.robot.path, mech.robot.name, pairs, mech.is_urdf))
    return with_approval_reasons(out, bodies, settings.approvals)
