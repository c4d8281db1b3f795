"""Mesh helpers shared by the readers and later stages: closedness, cleaning, shells.

``is_closed`` is the one test of "this mesh bounds a volume" in meshcheck; ``verify`` and
``decompose`` call it too.
"""

from __future__ import annotations

import warnings

import numpy as np
import trimesh

from .errors import InputError, MeshcheckWarning
from .geometry import topology

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
    result = topology.is_closed(mesh.faces)
    if cache is not None:
        cache[_CLOSED_KEY] = result
    return result


def as_mesh(vertices: np.ndarray, faces: np.ndarray, *, closed: bool | None = None):
    """A ``trimesh.Trimesh`` of arrays ``clean_arrays`` returned, taken as they are.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    closed : bool, optional
        ``topology.is_closed(faces)`` when the caller knows it; kept with the mesh so
        ``is_closed`` does not decide it again.
    """
    mesh = trimesh.Trimesh(vertices, faces, process=False, validate=False)
    if closed is not None:
        mesh._cache.update({_CLOSED_KEY: bool(closed)})
    return mesh


#: Address space a manifold3d boolean needs beyond its inputs, with a margin of 2.5: a boolean of
#: a 327,680-triangle sphere and a box crashed with 40 MB left and ran with 46 MB (about 140 bytes
#: a triangle), its thread pool aside.
BOOLEAN_BASE_BYTES = 32 << 20
BOOLEAN_TRIANGLE_BYTES = 256


def check_boolean_room(triangles: int, what: str, *, inputs: int = 1) -> None:
    """Raise ``MemoryError`` when the address space left (``ulimit -v``) cannot hold a
    manifold3d ``what`` ("boolean", "union") of ``triangles`` triangles: manifold3d crashes
    (SIGSEGV) instead of raising when an allocation fails. ``inputs`` scales the room asked
    per triangle (a union's inputs and its result)."""
    from .execute import address_space_left

    left = address_space_left()
    if left is not None and left < BOOLEAN_BASE_BYTES + inputs * BOOLEAN_TRIANGLE_BYTES * triangles:
        raise MemoryError(
            f"{left} bytes of address space left for a {what} of {triangles} triangles"
        )


def outward_faces(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Faces of a closed mesh wound outward (flipped when its signed volume is negative)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    signed = np.einsum("ij,ij->", a - a.mean(axis=0), np.cross(b - a, c - a))
    return f[:, ::-1].copy() if signed < 0 else f


def manifold_solid(vertices: np.ndarray, faces: np.ndarray):
    """The closed, outward mesh as a ``manifold3d.Manifold`` (its arrays copied, as nanobind
    wants them writable and contiguous); None when manifold3d does not take it as a solid."""
    import manifold3d

    solid = manifold3d.Manifold(
        manifold3d.Mesh64(
            vert_properties=np.array(vertices, dtype=np.float64, order="C"),
            tri_verts=np.array(faces, dtype=np.uint64, order="C"),
        )
    )
    return solid if solid.status() == manifold3d.Error.NoError else None


def warn(name: str, reason: str) -> None:
    """Issue a ``MeshcheckWarning`` reading ``NAME: reason``."""
    warnings.warn(MeshcheckWarning(f"{name}: {reason}"), stacklevel=3)


def clean_arrays(
    vertices, faces, name: str, *, max_coordinate: float = np.inf, shells: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Validated mesh arrays: finite, vertices merged, triangles with a repeated vertex dropped.

    Vertices are merged by ``merge_vertices``; triangles of zero area with three distinct
    vertices are kept: on a closed surface they stitch a T-vertex to the edge it splits, and
    dropping them would open a crack. Vertices no triangle uses are dropped.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    name : str
        The part name errors and warnings start with.
    max_coordinate : float
        Largest absolute coordinate accepted.
    shells : (n,) int64, optional
        A label per vertex: vertices of different labels are never merged (``merge_vertices``).

    Returns
    -------
    vertices : (k, 3) float64
        Each kept vertex once, in the order of first use in ``vertices``.
    faces : (j, 3) int64
        The triangles kept, in file order.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    with np.errstate(all="ignore"):
        largest = float(np.max(np.abs(vertices))) if len(vertices) else 0.0
    if not np.isfinite(largest):
        bad = int(np.count_nonzero(~np.all(np.isfinite(vertices), axis=1)))
        raise InputError(name, f"{bad} vertices have NaN or infinite coordinates")
    if largest > max_coordinate:
        raise InputError(
            name,
            f"its coordinates reach {largest:.3g}, beyond the {max_coordinate:g} "
            "meshcheck can check exactly",
        )
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(name, "triangles refer to vertices that do not exist")
    v, f = merge_vertices(vertices, faces, shells=shells)
    repeated, flat = topology.degenerate_triangles(v, f)
    if flat.all():
        raise InputError(name, "every triangle is degenerate (zero area)")
    if repeated.any():
        count = int(repeated.sum())
        warn(name, f"dropped {count} degenerate triangles (repeated vertices)")
        v, f = _drop_unreferenced(v, f[~repeated])
    return v, f


#: Decimal digits vertex coordinates are compared to when merging: trimesh's ``tol.merge`` (1e-8).
MERGE_DIGITS = 8
_MERGE_SCALE = 10.0**MERGE_DIGITS
#: Scaled coordinates below this fit an int64 key with room to spare (2**62).
_MERGE_KEY_LIMIT = float(1 << 62)


def merge_vertices(
    vertices: np.ndarray, faces: np.ndarray, *, shells: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Merge the vertices that are equal to ``MERGE_DIGITS`` decimals; drop unused ones.

    trimesh's rule (``Trimesh.merge_vertices``): two vertices the faces use are one when each
    coordinate ``x`` rounds to the same integer ``round(x * 1e8)`` (half to even). A coordinate
    whose ``x * 1e8`` leaves the int64 range (``abs(x) > 4.6e10``, where neighbouring doubles
    are already 1e-5 apart) is compared exactly; trimesh would wrap it.

    Parameters
    ----------
    vertices : (n, 3) float64
        Finite.
    faces : (m, 3) int64
        Indices into ``vertices``.
    shells : (n,) int64, optional
        A label per vertex; vertices of different labels are not merged (the closed shells of
        a part made of solids that share faces stay apart).

    Returns
    -------
    vertices : (k, 3) float64
        The first vertex of each group, groups in the order of their first vertex (as trimesh
        orders them).
    faces : (m, 3) int64
        ``faces`` renumbered.

    Examples
    --------
    >>> v = np.array([[0.0, 0, 0], [1, 0, 0], [1e-9, 0, 0], [0, 1, 0], [5, 5, 5]])
    >>> merged, f = merge_vertices(v, np.array([[0, 1, 3], [2, 3, 1]]))
    >>> merged.tolist(), f.tolist()
    ([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2], [0, 2, 1]])
    """
    if len(vertices) == 0 or len(faces) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    every = bool(used.all())
    points = vertices if every else vertices[used]
    scaled = np.rint(points * _MERGE_SCALE)
    if float(np.max(np.abs(scaled))) < _MERGE_KEY_LIMIT:
        keys = scaled.astype(np.int64)
    else:  # rounded keys where they fit, the exact coordinate where they do not
        big = ~(np.abs(scaled) < _MERGE_KEY_LIMIT)
        small = np.where(big, np.iinfo(np.int64).min, scaled).astype(np.int64)
        exact = np.where(big, points + 0.0, 0.0).view(np.int64)  # + 0.0: no -0.0 bits
        keys = np.concatenate([small, exact], axis=1)
    if shells is not None:
        labels = np.asarray(shells, dtype=np.int64)
        keys = np.concatenate([keys, (labels if every else labels[used])[:, None]], axis=1)
    first, inverse = topology.group_rows(keys)
    if every:
        return vertices[first], inverse[faces]
    index = np.flatnonzero(used)
    renumber = np.zeros(len(vertices), dtype=np.int64)
    renumber[index] = inverse
    return vertices[index[first]], renumber[faces]


def _drop_unreferenced(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices the faces use, in their order, and the faces renumbered."""
    used = np.zeros(len(v), dtype=bool)
    used[f] = True
    renumber = np.cumsum(used) - 1
    return v[used], renumber[f]


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
    face_label, n = shell_labels(mesh)
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


def shell_labels(mesh: trimesh.Trimesh) -> tuple[np.ndarray, int]:
    """Connected-component label of each face, numbered by first appearance; and their count."""
    return topology.shell_labels(mesh.faces, len(mesh.vertices))


def _winding_number(mesh: trimesh.Trimesh, point: np.ndarray) -> float:
    """Generalised winding number of a closed mesh around ``point`` (1 inside, 0 outside): the
    compiled kernel the verify stage uses (``geometry.triangles.winding_numbers``)."""
    from .geometry.triangles import winding_numbers

    points = np.asarray(point, dtype=np.float64).reshape(1, 3)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return float(winding_numbers(points, v, np.asarray(mesh.faces, dtype=np.int64))[0])
