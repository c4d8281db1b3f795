"""The SRDF audit (``--audit-srdf``): each link pair an SRDF disables, swept over the joint
ranges, proven never in contact or shown colliding at a witness pose.

Only the pairs the SRDF names are swept (``run.sweep_mechanism`` with ``pairs``), their links'
convex pieces made beforehand (``run.mechanism_pieces``); with ``--sweep`` the whole robot's
sweep is read instead. A link without collision geometry never collides: its pairs are never,
with no box evaluated. Pairs the sweep's work budget did not reach are undecided. What fails
the run is ``outcome.CheckResult``'s to say.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..load import Body
from ..load.robot import Mechanism
from ..results import AuditedPair, PairSweep, RobotSweep, SrdfAudit, SweepStatus
from .mechanisms import audited_pairs, is_audited
from .run import sweep_mechanism


def audit_srdf(
    bodies: Sequence[Body],
    mechanisms: Sequence[Mechanism],
    settings,
    *,
    pieces: dict[int, list[np.ndarray]],
    sweeps: Sequence[RobotSweep] = (),
) -> SrdfAudit | None:
    """The audit of the SRDF a robot of the run carries (``Mechanism.srdf``); None without one.

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts, at its pose.
    mechanisms : sequence of Mechanism
        ``load.Assembly.mechanisms``.
    settings : Settings
        The joints swept (``motion.sweep``: all when None or empty), the reasons audited
        (``motion.audit_reasons``) and the tolerance.
    pieces : dict of int -> list of (n_i, 3) float64
        Convex pieces of the audited links' parts (``run.mechanism_pieces``).
    sweeps : sequence of RobotSweep
        The run's sweeps (``--sweep``): the robot's, when there, answers for its pairs.
    """
    mech = next((m for m in mechanisms if m.srdf is not None), None)
    if mech is None:
        return None
    srdf, motion = mech.srdf, settings.motion
    wanted = audited_pairs(srdf, motion)
    swept = next((r for r in sweeps if r.path == mech.robot.path), None)
    if swept is None:
        pairs = sweep_mechanism(
            mech, bodies, pieces, motion, tolerance=settings.tolerance, pairs=wanted
        )
    else:
        pairs = swept.pairs
    by_pair = {frozenset((p.a, p.b)): p for p in pairs}
    audited = []
    for entry in srdf.pairs:
        if not is_audited(entry.reason, motion.audit_reasons):
            continue
        key = frozenset((entry.a, entry.b))
        sweep = by_pair.get(key)
        if sweep is None and len(key) == 2 and all(link in mech.parts for link in key):
            # both links have geometry: the work budget ran out before the pair
            sweep = PairSweep(entry.a, entry.b, SweepStatus.UNDECIDED)
        elif sweep is None:  # a link without collision geometry: nothing of it can collide
            sweep = PairSweep(entry.a, entry.b, SweepStatus.NEVER)
        sweep = dataclasses.replace(sweep, is_adjacent=key in mech.adjacent)
        audited.append(AuditedPair(entry.a, entry.b, entry.reason, sweep, entry.line, entry.span))
    return SrdfAudit(
        srdf.path,
        mech.robot.path,
        motion.audit_reasons,
        tuple(audited),
        unaudited=len(srdf.pairs) - len(audited),
        source=srdf.data,
    )


__all__ = ["audit_srdf"]
