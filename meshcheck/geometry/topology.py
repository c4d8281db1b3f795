"""Mesh connectivity for the load stage: equal rows of keys, degenerate triangles, closedness,
connected shells.

The work is C++ (``src/topology.hpp``, compiled at ``pip install``); these functions convert
their arguments and raise ``ValueError`` on malformed input. Every answer depends on the arrays
alone (first-appearance order, no hash-table order), so it is the same on every run.
"""

from __future__ import annotations

import numpy as np

from . import _kernels

__all__ = ["degenerate_triangles", "group_rows", "is_closed", "shell_labels"]


def group_rows(keys, *, by_sorting: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Group the equal rows of an integer array, numbering groups by their first row.

    A hash table does it in linear time; keys that collide in it beyond a fixed amount of probing
    (a crafted file) are grouped by sorting instead, in O(n log n). Both give the same answer.

    Parameters
    ----------
    keys : (n, c) int64
    by_sorting : bool
        Sort from the start (the path crafted keys take; for tests).

    Returns
    -------
    first : (g,) int64
        The first row of each group, increasing.
    inverse : (n,) int64
        The group of each row: ``keys[first][inverse]`` equals ``keys``.

    Examples
    --------
    >>> first, inverse = group_rows([[5, 0, 0], [1, 2, 3], [5, 0, 0]])
    >>> first.tolist(), inverse.tolist()
    ([0, 1], [0, 1, 0])
    """
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    if keys.ndim != 2:
        keys = keys.reshape(len(keys), -1)
    return _kernels.group_rows(keys, bool(by_sorting))


def degenerate_triangles(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Which triangles name a vertex twice, and which have no area at all.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
        Indices in ``[0, n)``.

    Returns
    -------
    repeated : (m,) bool
        The triangle names one vertex twice or three times.
    flat : (m,) bool
        Repeated, or its cross product ``(b - a) x (c - a)`` is exactly zero (computed with
        plain double operations, as numpy computes it).

    Examples
    --------
    >>> v = [[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]
    >>> repeated, flat = degenerate_triangles(v, [[0, 1, 3], [0, 1, 2], [0, 0, 3]])
    >>> repeated.tolist(), flat.tolist()
    ([False, False, True], [False, True, True])
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
    return _kernels.degenerate_triangles(v, np.ascontiguousarray(faces, dtype=np.int64))


def is_closed(faces) -> bool:
    """True when every directed edge ``(a, b)`` of ``faces (m, 3)`` occurs exactly once and its
    reverse ``(b, a)`` occurs too (a closed, consistently oriented surface); False for no faces
    or a face with a repeated vertex.

    Examples
    --------
    >>> tetrahedron = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]
    >>> is_closed(tetrahedron), is_closed(tetrahedron[1:])
    (True, False)
    """
    return _kernels.is_closed(np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3))


def shell_labels(faces, n_vertices: int) -> tuple[np.ndarray, int]:
    """The connected shell of each triangle (triangles sharing a vertex are connected).

    Parameters
    ----------
    faces : (m, 3) int64
        Indices in ``[0, n_vertices)``.
    n_vertices : int

    Returns
    -------
    label : (m,) int64
        Shells numbered in the order of their first triangle.
    count : int

    Examples
    --------
    >>> label, count = shell_labels([[3, 4, 5], [0, 1, 2], [5, 4, 6]], 7)
    >>> label.tolist(), count
    ([0, 1, 0], 2)
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    return _kernels.shell_labels(faces, int(n_vertices))
