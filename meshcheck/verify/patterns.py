"""Patterns: findings between copies of one pair of geometries at one relative placement.

Forty brackets, each with its bolt clipping it the same way, are one design error repeated forty
times (IfcClash's smart groups, Navisworks' grouping). Two findings belong to one pattern when
their parts have the same geometries (``local_geometry``'s digest: the mesh content up to
translation) and the second part sits in the first's frame at the same relative placement, within
the touching tolerance: every vertex of it lies within the tolerance of where it lies in the
other finding. The verify stage decided each finding alone; this stage only labels them
(``Finding.pattern``), and ``results.clash_groups`` groups the labels. A pattern's key hashes the
two geometries and one member's relative placement; for STEP solids, their products' B-rep and
the products' own frames, which another deflection does not move (as their finding IDs).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence

import numpy as np

from ..results import GROUPED_STATUSES, Finding
from ..tolerances import mesh_tolerance
from .duplicates import clusters


def with_patterns(
    bodies: Sequence,
    findings: Sequence[Finding],
    geometry: dict,
    *,
    tolerance: float | None,
) -> list[Finding]:
    """``findings`` with ``pattern`` set on the interference and clearance findings that repeat.

    The two parts of each are replaced by their geometry classes (``geometry_classes``), then
    the placements of the second in the first's frame are clustered within the tolerance.

    Parameters
    ----------
    bodies : sequence of load.Body
    findings : sequence of Finding
    geometry : dict
        ``load.local_geometries(bodies)``.
    tolerance : float or None
        The user's touching tolerance, model units; None: the smallest tolerance that decided a
        finding of the candidate pattern (``Finding.tolerance``).

    Returns
    -------
    list of Finding
        In the same order; a finding of a pattern of two or more gets the pattern's 12-hex-digit
        key (hashing the two geometries and one member's relative placement), others keep ``""``.
    """
    index = {b.name: k for k, b in enumerate(bodies)}
    grouped = [f for f in findings if f.status in GROUPED_STATUSES]
    used = [bodies[index[name]] for f in grouped for name in (f.a, f.b)]
    kind = _named_classes(used, geometry_classes(used, geometry, tolerance=tolerance))
    by_pair: dict[tuple[str, str, str], list[int]] = {}
    for n, f in enumerate(findings):
        if f.status in GROUPED_STATUSES:
            a, b = (kind[id(bodies[index[name]].mesh)] for name in (f.a, f.b))
            by_pair.setdefault((str(f.status), *sorted((a, b))), []).append(n)
    keys = [""] * len(findings)
    for (_, first, second), members in sorted(by_pair.items()):
        if len(members) < 2:
            continue
        points, stable, owner = [], [], []
        for n in members:
            for point, key_point in _relative(
                bodies, index, geometry, kind, findings[n], first, second
            ):
                points.append(point)
                stable.append(key_point)
                owner.append(n)
        tol = tolerance
        if tol is None:
            tol = min((findings[n].tolerance or 0.0) for n in members)
        for rows in _joined(np.array(points), np.array(owner), tol):
            representative = min(stable[k].tobytes() for k in rows)
            h = hashlib.sha256(f"pattern\0{first}\0{second}\0".encode())
            h.update(representative)
            key = h.hexdigest()[:12]
            for k in rows:
                keys[owner[k]] = key
    return [
        dataclasses.replace(f, pattern=key) if key else f
        for f, key in zip(findings, keys, strict=True)
    ]


def geometry_classes(bodies: Sequence, geometry: dict, *, tolerance: float | None) -> dict:
    """A class for each distinct mesh of ``bodies``: meshes with the same faces whose vertices,
    up to translation, agree within the tolerance share one (see the module docstring).

    Parameters
    ----------
    bodies : sequence of load.Body
    geometry : dict
        ``load.local_geometries`` of (at least) ``bodies``.
    tolerance : float or None
        The user's touching tolerance, model units; None: each mesh's own, as for a pair
        (``tolerances.mesh_tolerance``).

    Returns
    -------
    dict
        ``id(mesh)`` -> the class: the ``local_geometry`` digest of its first member, meshes
        taken in digest order (so the classes are a function of the meshes alone).
    """
    meshes = {id(b.mesh): b for b in bodies}
    by_faces: dict[tuple[int, bytes], list[tuple[str, int]]] = {}
    for key in meshes:
        local, faces, _, digest = geometry[key]
        shape = (len(local), hashlib.sha256(faces.tobytes()).digest())
        by_faces.setdefault(shape, []).append((digest, key))
    out = {}
    for members in by_faces.values():
        tols = {key: _mesh_tolerance(meshes[key], geometry[key], tolerance) for _, key in members}
        out.update(_classes(sorted(members), geometry, tols))
    return out


def _classes(members: list[tuple[str, int]], geometry: dict, tols: dict) -> dict:
    """``geometry_classes`` of meshes with the same triangles, in digest order: each joins the
    first earlier class whose first mesh agrees with it within both tolerances. Classes are
    found by the box of their local vertices on a grid of the largest tolerance, so a mesh is
    compared with the classes in its cell and the 26 around it only."""
    cell = max(tols.values())
    grid: dict[tuple, list[tuple[int, str, int]]] = {}  # cell -> (class number, digest, mesh)
    out: dict[int, str] = {}
    count = 0
    for digest, key in members:
        local = geometry[key][0]
        extent = local.max(axis=0) if len(local) else np.zeros(3)
        home = tuple(np.floor(extent / cell).astype(np.int64)) if cell > 0 else (digest,)
        near = [home] if cell <= 0 else [tuple(np.add(home, d)) for d in _NEIGHBOURS]
        match = None
        for _number, first, other in sorted(c for n in near for c in grid.get(n, ())):
            gap = np.abs(local - geometry[other][0]).max(initial=0.0)
            if digest == first or gap <= min(tols[key], tols[other]):
                match = first
                break
        if match is None:
            grid.setdefault(home, []).append((count, digest, key))
            count += 1
            match = digest
        out[key] = match
    return out


_NEIGHBOURS = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)]


def _mesh_tolerance(body, local_geometry: tuple, tolerance: float | None) -> float:
    """How far two copies' local vertices may differ and be one geometry, the mesh's units."""
    if tolerance is None:
        local, _, corner, _ = local_geometry
        return mesh_tolerance(local, corner, is_float32=body.is_float32)
    scale = abs(float(np.linalg.det(np.asarray(body.transform)[:3, :3]))) ** (1.0 / 3.0)
    return tolerance / scale if scale > 0 else 0.0


def _named_classes(bodies: Sequence, kind: dict) -> dict:
    """``kind`` (``geometry_classes``) with each class named by the B-rep product of the STEP
    solids it renders when they are one product's (``Body.source_digest``: the same at any
    deflection, so the classes' order and the keys are too), else by its meshes' digest."""
    sources: dict[str, set[str]] = {}
    for body in bodies:
        sources.setdefault(kind[id(body.mesh)], set()).add(body.source_digest)
    named = {c: next(iter(s)) if len(s) == 1 and "" not in s else c for c, s in sources.items()}
    return {mesh: named[c] for mesh, c in kind.items()}


def _relative(bodies, index, geometry, kind, finding: Finding, first: str, second: str):
    """Where the part of geometry ``second`` sits in the frame of the part of geometry
    ``first``, as 12 numbers in model units (the rotation times the second geometry's size,
    then the origin); both ways round when the two geometries are one. Each with what its key
    hashes: the same, or for a STEP solid the placement of its product's own frame (its
    rotation unscaled), which its triangles do not move."""
    parts = [bodies[index[finding.a]], bodies[index[finding.b]]]
    if kind[id(parts[0].mesh)] != first:
        parts.reverse()
    frames = []
    for body in parts:
        local, _, corner, _ = geometry[id(body.mesh)]
        frame = np.asarray(body.transform, dtype=np.float64).copy()
        frame[:3, 3] = frame[:3, :3] @ corner + frame[:3, 3]  # the local geometry's frame
        size = float(np.linalg.norm(local.max(axis=0))) if len(local) else 0.0
        product = (np.asarray(body.transform, dtype=np.float64), 1.0)
        frames.append(((frame, size), product if body.source_digest else (frame, size)))
    orders = [(0, 1), (1, 0)] if first == second else [(0, 1)]
    return [tuple(_placed(frames[i][k], frames[j][k]) for k in (0, 1)) for i, j in orders]


def _placed(first: tuple[np.ndarray, float], second: tuple[np.ndarray, float]) -> np.ndarray:
    """12 numbers: frame ``second[0]`` in frame ``first[0]``, its rotation times ``second[1]``,
    in model units."""
    (frame_i, _), (frame_j, size_j) = first, second
    scale = abs(float(np.linalg.det(frame_i[:3, :3]))) ** (1.0 / 3.0)
    relative = np.linalg.solve(frame_i, frame_j)
    return scale * np.concatenate([relative[:3, :3].ravel() * size_j, relative[:3, 3]])


def _joined(points: np.ndarray, owner: np.ndarray, tol: float) -> list[list[int]]:
    """Rows of ``points`` in groups of two or more findings: points within the radius are
    linked (``duplicates.clusters``), and so are the points of one finding."""
    linked = clusters(points, tol)
    parent = {int(n): int(n) for n in owner}

    def root(n: int) -> int:
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for rows in linked:
        for k in rows[1:]:
            a, b = root(int(owner[rows[0]])), root(int(owner[k]))
            parent[max(a, b)] = min(a, b)
    groups: dict[int, list[int]] = {}
    for k, n in enumerate(owner):
        groups.setdefault(root(int(n)), []).append(k)
    return [rows for rows in groups.values() if len({int(owner[k]) for k in rows}) > 1]
