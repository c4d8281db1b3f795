"""Shells of one mesh that share volume: the loader's warning that a file's bodies overlap.

The exact test is the verify stage's own (``pair.verify_pair``) on each pair of closed shells whose
boxes overlap; the loader calls this on files with more than one shell.
"""

from __future__ import annotations

import numpy as np
import trimesh

from ..geometry.broadphase import candidate_pairs
from ..mesh import is_closed, shell_labels, split_shells
from ..results import Verdict
from .pair import verify_pair


def overlapping_shells(mesh: trimesh.Trimesh) -> tuple[int, int] | None:
    """Two closed shells of ``mesh`` that share volume, as 1-based shell numbers, or None.

    Shells are numbered as ``split_shells`` lists them. Shells that only touch (within 1e-6 of
    their size) do not count; the exact test is ``verify.verify_pair``.
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
        tolerance = 1e-6 * float(np.linalg.norm(np.maximum(a.extents, b.extents)))
        shared = np.minimum(upper[i], upper[j]) - np.maximum(lower[i], lower[j])
        if shared.min() <= tolerance:  # boxes meeting face to face (an assembly export's
            continue  # neighbours) cannot share a solid thicker than the tolerance
        verdict = verify_pair(a, b, tolerance=tolerance, clearance=None)
        if verdict.status == Verdict.INTERFERENCE:
            return solid[i] + 1, solid[j] + 1
    return None
