"""Findings on a part made of several collision elements (a URDF link's) name the elements they
involve.

A link is one part: its elements are joined into one mesh (``load.urdf.join_elements``) and
never checked against each other. So that a finding can still be traced to the ``<collision>``
to fix, each element of such a part is checked against the other part by the verify stage's own
test (``pair.verify_pair``, at the finding's tolerance and, for a clearance finding, the
clearance): the elements that interfere, touch or come within the clearance are the ones it
involves (``Finding.elements``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import trimesh

from ..load import Body
from ..results import CollisionElement, Finding, Verdict
from .pair import verify_pair


def with_elements(
    bodies: Sequence[Body], findings: Sequence[Finding], *, clearance: float | None
) -> list[Finding]:
    """``findings``, each between a part of several collision elements and another part given
    the elements it involves (``Finding.elements``, the first part's then the second's).

    Parameters
    ----------
    bodies : sequence of Body
        The run's parts (``Body.elements``).
    findings : sequence of Finding
    clearance : float or None
        The run's required clearance, for clearance findings.
    """
    by_name = {b.name: b for b in bodies}
    out = []
    for f in findings:
        a, b = by_name.get(f.a), by_name.get(f.b)
        if (
            f.status == Verdict.DUPLICATE
            or a is None
            or b is None
            or (len(a.elements) < 2 and len(b.elements) < 2)
        ):
            out.append(f)
            continue
        reach = clearance if f.status == Verdict.CLEARANCE else None
        involved = (*_involved(a, b, f, reach), *_involved(b, a, f, reach))
        out.append(dataclasses.replace(f, elements=involved))
    return out


def _involved(
    part: Body, other: Body, finding: Finding, clearance: float | None
) -> tuple[CollisionElement, ...]:
    """The elements of ``part`` (none when it has fewer than two) that the verify stage finds
    interfering, touching or within ``clearance`` of ``other``; every element when none does
    (the finding is the union's: an element buried in another, met only as a whole)."""
    if len(part.elements) < 2:
        return ()
    tolerance = finding.tolerance if finding.tolerance is not None else 0.0
    found = []
    for element in part.elements:
        mesh = trimesh.Trimesh(element.vertices, element.faces, process=False)
        mesh.apply_transform(part.transform)
        verdict = verify_pair(mesh, other.world, tolerance=tolerance, clearance=clearance)
        if verdict.status != Verdict.CLEAR:
            found.append(element.element)
    return tuple(found) or tuple(e.element for e in part.elements)


__all__ = ["with_elements"]
