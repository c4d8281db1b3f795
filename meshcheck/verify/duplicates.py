"""Duplicates: a part placed twice at the same spot, decided before any pair is verified.

Two parts are copies of each other when their geometry has the same digest (``local_geometry``:
the mesh up to translation) and their world placements agree within the touching tolerance:
every vertex of one lies within the tolerance of its twin in the other. Such a set is one
``duplicate`` finding (a doubled component is a modelling error), not a deep interference per
pair; its pairs are left out of the verify stage, so 2,000 coincident copies cost one grouping.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np

from ..results import Finding, Location, PairVerdict, Verdict
from ..tolerances import mesh_tolerance

#: Tolerance -> search radius in the 12-number placement space (scaled rotation, translation):
#: a distance r there moves no vertex by more than sqrt(2) r, so r = tol / 2 keeps every vertex
#: within the tolerance.
_RADIUS_FRACTION = 0.5


def duplicate_sets(bodies: Sequence, geometry: dict, *, tolerance: float | None) -> list[list[int]]:
    """Sets of body indices (each sorted, two or more) that are copies at the same spot.

    Parameters
    ----------
    bodies : sequence of load.Body
    geometry : dict
        ``load.local_geometries(bodies)``.
    tolerance : float or None
        The user's touching tolerance, model units; None: the part's own
        (``tolerances.mesh_tolerance``).
    """
    by_digest: dict[str, list[int]] = {}
    for k, body in enumerate(bodies):
        by_digest.setdefault(geometry[id(body.mesh)].digest, []).append(k)
    sets = []
    for members in by_digest.values():
        if len(members) < 2:
            continue
        first = bodies[members[0]]
        local, _, corner, _ = geometry[id(first.mesh)]
        diagonal = float(np.linalg.norm(local.max(axis=0))) if len(local) else 0.0
        tol = tolerance
        if tol is None:
            tol = mesh_tolerance(local, corner, is_float32=first.is_float32)
        features = _placements([bodies[k] for k in members], geometry, diagonal)
        sets += [[members[i] for i in group] for group in clusters(features, tol)]
    return sorted(sets)


def _placements(bodies: Sequence, geometry: dict, diagonal: float) -> np.ndarray:
    """Each body's local-to-world map as 12 numbers, ``(n, 12)``: rotation x diagonal, then
    the origin (where its local geometry's corner lands)."""
    transforms = np.array([b.transform for b in bodies], dtype=np.float64).reshape(-1, 4, 4)
    corners = np.array([geometry[id(b.mesh)].corner for b in bodies]).reshape(-1, 3, 1)
    rotation, shift = transforms[:, :3, :3], transforms[:, :3, 3]
    origin = (rotation @ corners)[:, :, 0] + shift
    return np.concatenate([(rotation * diagonal).reshape(-1, 9), origin], axis=1)


def clusters(features: np.ndarray, tol: float) -> list[list[int]]:
    """Groups (two or more rows) of ``features`` linked by distances within the radius."""
    unique, inverse = np.unique(features, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    parent = np.arange(len(unique))
    if len(unique) > 1 and tol > 0:
        from scipy.spatial import cKDTree

        near = cKDTree(unique).query_pairs(_RADIUS_FRACTION * tol, output_type="ndarray")
        for i, j in near:
            ri, rj = _root(parent, int(i)), _root(parent, int(j))
            parent[max(ri, rj)] = min(ri, rj)
    roots = np.array([_root(parent, int(u)) for u in inverse])
    groups: dict[int, list[int]] = {}
    for row, root in enumerate(roots):
        groups.setdefault(int(root), []).append(row)
    return [g for g in groups.values() if len(g) > 1]


def _root(parent: np.ndarray, i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = int(parent[i])
    return i


def duplicate_findings(bodies: Sequence, sets: list[list[int]], geometry: dict) -> list[Finding]:
    """One ``duplicate`` finding per set: its first two names (sorted) as ``a`` and ``b``, every
    name in ``members``, the box of the first copy as its location, a stable set ID."""
    out = []
    for members in sets:
        names = sorted(bodies[k].name for k in members)
        local, _, corner, digest = geometry[id(bodies[members[0]].mesh)]
        sources = sorted({bodies[k].source_digest for k in members} - {""})
        if sources:  # STEP solids: the products they render, not this rendering of them
            digest = "\0".join(sources)
        transform = np.asarray(bodies[members[0]].transform, dtype=np.float64)
        world = (local + corner) @ transform[:3, :3].T + transform[:3, 3]
        lower, upper = world.min(axis=0), world.max(axis=0)
        verdict = PairVerdict(
            Verdict.DUPLICATE, 0.0, location=Location((lower + upper) / 2, lower, upper)
        )
        out.append(
            Finding(
                a=names[0],
                b=names[1],
                verdict=verdict,
                id=duplicate_id(names, digest, [bodies[k].transform for k in members]),
                members=tuple(names),
            )
        )
    return out


def duplicate_id(names: Sequence[str], digest: str, placements: Sequence[np.ndarray] = ()) -> str:
    """Stable 12-hex-digit ID of a duplicate set: its sorted names, the geometry's digest (for
    STEP solids, their products' B-rep: ``Body.source_digest``) and the copies' placements
    (moving the set elsewhere lapses an approval by ID, as for any finding)."""
    text = "\0".join(["duplicate", digest, *sorted(names)])
    h = hashlib.sha256(text.encode("utf-8", "surrogateescape"))
    for placement in sorted((np.asarray(p, dtype=np.float64) + 0.0).tobytes() for p in placements):
        h.update(b"\0@" + placement)
    return h.hexdigest()[:12]
