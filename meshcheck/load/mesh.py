"""Mesh helpers shared by the readers and later stages: closedness, cleaning, shells.

``is_closed`` is the one test of "this mesh bounds a volume" in meshcheck; ``verify`` and
``decompose`` call it too.
"""

from __future__ import annotations

import warnings

import numpy as np
import trimesh

from ..errors import InputError, MeshcheckWarning

_CLOSED_KEY = "meshcheck_is_closed"  # trimesh's per-mesh cache, invalidated when the mesh changes


def is_closed(mesh: trimesh.Trimesh) -> bool:
    """True when a mesh is closed and consistently oriented, so it bounds a volume.

    Decided on the mesh as given, from its faces alone: every directed edge ``(a, b)`` of a
    triangle occurs exactly once and its reverse ``(b, a)`` occurs too, so every edge joins exactly
    two triangles that agree on their orientation. Triangles of zero area whose three vertices are
    distinct (a collinear T-vertex) count like any other: they close the surface.

    Examples
    --------
    >>> cube = trimesh.creation.box()
    >>> is_closed(cube), is_closed(trimesh.Trimesh(cube.vertices, cube.faces[1:]))
    (True, False)
    """
    cache = getattr(mesh, "_cache", None)
    if cache is not None and cache[_CLOSED_KEY] is not None:
        return bool(cache[_CLOSED_KEY])
    result = _is_closed(np.asarray(mesh.faces, dtype=np.int64))
    if cache is not None:
        cache[_CLOSED_KEY] = result
    return result


def _is_closed(faces: np.ndarray) -> bool:
    if len(faces) == 0:
        return False
    tail = faces.ravel()
    head = faces[:, [1, 2, 0]].ravel()
    if np.any(tail == head):
        return False
    n = int(faces.max()) + 1
    keys = np.sort(tail * n + head)
    if np.any(keys[1:] == keys[:-1]):  # an edge used twice the same way: not one orientation
        return False
    reverse = head * n + tail
    at = np.searchsorted(keys, reverse)
    return bool(np.all(at < len(keys)) and np.all(keys[np.minimum(at, len(keys) - 1)] == reverse))


def warn(name: str, reason: str) -> None:
    """Issue a ``MeshcheckWarning`` reading ``NAME: reason``."""
    warnings.warn(MeshcheckWarning(f"{name}: {reason}"), stacklevel=3)


def clean_mesh(vertices, faces, name: str, *, max_coordinate: float = np.inf) -> trimesh.Trimesh:
    """Validated mesh: finite, vertices merged, triangles with a repeated vertex dropped.

    Triangles of zero area with three distinct vertices are kept: on a closed surface they
    stitch a T-vertex to the edge it splits, and dropping them would open a crack.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    name : str
        The part name errors and warnings start with.
    max_coordinate : float
        Largest absolute coordinate accepted.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if not np.all(np.isfinite(vertices)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(vertices), axis=1)))
        raise InputError(name, f"{bad} vertices have NaN or infinite coordinates")
    largest = float(np.max(np.abs(vertices))) if len(vertices) else 0.0
    if largest > max_coordinate:
        raise InputError(
            name,
            f"its coordinates reach {largest:.3g}, beyond the {max_coordinate:g} "
            "meshcheck can check exactly",
        )
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(name, "triangles refer to vertices that do not exist")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    f, v = mesh.faces, mesh.vertices
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    with np.errstate(all="ignore"):
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flat = repeated | ~np.any(cross != 0.0, axis=1)
    if flat.all():
        raise InputError(name, "every triangle is degenerate (zero area)")
    if repeated.any():
        count = int(repeated.sum())
        warn(name, f"dropped {count} degenerate triangles (repeated vertices)")
        mesh.update_faces(~repeated)
        mesh.remove_unreferenced_vertices()
    return mesh


# --------------------------------------------------------------------------------------------
# Shells


def split_shells(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """Split a mesh into its connected shells, keeping cavity linings with their outer shell.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Vertices merged.

    Returns
    -------
    shells : list of trimesh.Trimesh
        In the order of each part's first triangle in ``mesh``. A closed shell with negative
        signed volume (facing inward) that lies inside a closed outward shell is merged into the
        smallest such shell; every other shell is a part of its own.
    """
    face_label, n = _shell_labels(mesh)
    if n == 1:
        return [mesh]
    shells = [mesh.submesh([np.flatnonzero(face_label == k)], append=True) for k in range(n)]
    closed = [is_closed(s) for s in shells]
    volume = [float(s.volume) if c else 0.0 for s, c in zip(shells, closed, strict=True)]
    owner = list(range(n))
    for k in range(n):
        if not closed[k] or volume[k] >= 0.0:
            continue
        point = shells[k].vertices[0]
        containers = [
            j
            for j in range(n)
            if j != k and closed[j] and volume[j] > 0.0 and _winding_number(shells[j], point) > 0.5
        ]
        if containers:
            owner[k] = min(containers, key=lambda j: volume[j])
    out = []
    for k in range(n):
        if owner[k] != k:
            continue
        members = [j for j in range(n) if owner[j] == k]
        idx = np.flatnonzero(np.isin(face_label, members))
        out.append(mesh.submesh([idx], append=True) if len(members) > 1 else shells[k])
    return out


def _shell_labels(mesh: trimesh.Trimesh) -> tuple[np.ndarray, int]:
    """Connected-component label of each face, numbered by first appearance; and their count."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    faces = np.asarray(mesh.faces, dtype=np.int64)
    n_v = len(mesh.vertices)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n_v, n_v))
    n_comp, vertex_label = connected_components(graph, directed=False)
    face_label = vertex_label[faces[:, 0]]
    labels, first = np.unique(face_label, return_index=True)
    rank = np.empty(n_comp, dtype=np.int64)
    rank[labels[np.argsort(first)]] = np.arange(len(labels))
    return rank[face_label], len(labels)


def overlapping_shells(mesh: trimesh.Trimesh) -> tuple[int, int] | None:
    """Two closed shells of ``mesh`` that share volume, as 1-based shell numbers, or None.

    Shells are numbered as ``split_shells`` lists them. Shells that only touch (within 1e-6 of
    their size) do not count; the exact test is ``verify.verify_pair``.
    """
    if _shell_labels(mesh)[1] == 1:
        return None
    from ..broadphase import candidate_pairs
    from ..results import Verdict
    from ..verify import verify_pair

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


def _winding_number(mesh: trimesh.Trimesh, point: np.ndarray) -> float:
    """Generalised winding number of a closed mesh around ``point`` (1 inside, 0 outside): the
    compiled kernel the verify stage uses (``geometry.triangles.winding_numbers``)."""
    from ..geometry.triangles import winding_numbers

    points = np.asarray(point, dtype=np.float64).reshape(1, 3)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return float(winding_numbers(points, v, np.asarray(mesh.faces, dtype=np.int64))[0])
