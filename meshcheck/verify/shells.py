"""Shells of one mesh that share volume: the warning that a part's bodies overlap.

A part read from a file holding several closed shells (without ``--split``) is checked as one
part, so a clash between its own shells is never a finding; ``warn_overlapping_shells`` says so.
The exact test is the verify stage's own (``pair.verify_pair``) on each pair of closed shells
whose boxes overlap. The check runs it on the loaded bodies once the B-rep stage has sent its
first pairs to the workers (``pipeline.check_bodies``, ``verify.brep.decide_on_brep``'s
``meanwhile``), so its warnings follow the loader's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from ..geometry.broadphase import candidate_pairs
from ..load import Body
from ..mesh import is_closed, shell_labels, split_shells, warn
from ..results import Verdict
from ..tolerances import SHELL_TOUCH_FRACTION
from .pair import verify_pair


def warn_overlapping_shells(bodies: Sequence[Body]) -> None:
    """Warn once per mesh whose closed shells overlap each other (``overlapping_shells``).

    Instances of one mesh (``Body.mesh`` shared) are warned about once, under the first one's
    name; the message starts with the part name, as the loader's warnings do. A URDF link made
    of several collision elements (``Body.elements``) is left alone: they overlap by design,
    and the loader joined them into one solid (or said why it could not).
    """
    seen: set[int] = set()  # id(Body.mesh): instances share their mesh
    for body in bodies:
        if id(body.mesh) in seen or body.elements:
            continue
        seen.add(id(body.mesh))
        overlap = overlapping_shells(body.mesh, deflection=body.deflection)
        if overlap is not None:
            i, j = overlap
            warn(
                body.name,
                f"closed shells {i} and {j} of this part overlap each other; they are checked as "
                "one part, so their clash is not reported (use --split to check shells as parts)",
            )


def warn_nothing_to_compare(bodies: Sequence[Body], *, is_split: bool) -> None:
    """Warn when the run has one part: it passes with nothing compared.

    When that part's mesh holds several shells (and ``--split`` was not given), the warning
    suggests ``--split``, which makes each shell a part of its own.
    """
    if len(bodies) != 1:
        return
    body = bodies[0]
    reason = "the only part: nothing to compare it with, so the run passes without a check"
    shells = 1 if is_split else len(split_shells(body.mesh))
    if shells > 1:
        reason += f"; it holds {shells} shells: --split checks them against each other"
    warn(body.name, reason)


def overlapping_shells(mesh: trimesh.Trimesh, *, deflection: float = 0.0) -> tuple[int, int] | None:
    """Two closed shells of ``mesh`` that share volume, as 1-based shell numbers, or None.

    Shells are numbered as ``split_shells`` lists them. Shells that only touch (within
    ``SHELL_TOUCH_FRACTION`` of their size, plus twice ``deflection``: the shells of a
    tessellated solid lie within it of their faces, so solids that touch can show chords
    crossing by up to both deflections) do not count; the exact test is
    ``verify.verify_pair``.
    """
    if shell_labels(mesh)[1] == 1:
        return None
    shells = split_shells(mesh)
    solid = [k for k, s in enumerate(shells) if is_closed(s) and float(s.volume) > 0.0]
    if len(solid) < 2:
        return None
    lower = np.array([shells[k].bounds[0] for k in solid])
    upper = np.array([shells[k].bounds[1] for k in solid])
    for i, j in candidate_pairs(lower, upper, margin=0.0):
        a, b = shells[solid[i]], shells[solid[j]]
        size = float(np.linalg.norm(np.maximum(a.extents, b.extents)))
        tolerance = SHELL_TOUCH_FRACTION * size + 2.0 * deflection
        shared = np.minimum(upper[i], upper[j]) - np.maximum(lower[i], lower[j])
        if shared.min() <= tolerance:  # boxes meeting face to face (an assembly export's
            continue  # neighbours) cannot share a solid thicker than the tolerance
        verdict = verify_pair(a, b, tolerance=tolerance, clearance=None)
        if verdict.status == Verdict.INTERFERENCE:
            return solid[i] + 1, solid[j] + 1
    return None
