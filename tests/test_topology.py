"""The load stage's mesh kernels: vertex merging, degenerate triangles, closedness, shells.

Known answers first, then each kernel against an independent oracle: trimesh's own
``merge_vertices``, scipy's connected components, and numpy versions of the edge rules.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.errors import InputError
from meshcheck.geometry.topology import (
    degenerate_triangles,
    group_rows,
    is_closed,
    shell_labels,
)
from meshcheck.mesh import clean_arrays, merge_vertices

PROPERTY = settings(derandomize=True, deadline=None, max_examples=60)


def tetrahedron(offset=0):
    return (np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]) + offset).astype(np.int64)


# ---------------------------------------------------------------------------------------------
# Known answers


def test_closed_known_answers():
    box = trimesh.creation.box()
    faces = np.asarray(box.faces)
    assert is_closed(faces)
    assert not is_closed(faces[1:])  # a hole
    assert not is_closed(faces[:, ::-1][[0]].tolist() + faces[1:].tolist())  # one face flipped
    assert not is_closed(np.concatenate([faces, faces[:1]]))  # a face twice
    assert not is_closed(np.zeros((0, 3), dtype=np.int64))
    assert not is_closed([[0, 0, 1], [1, 0, 0]])  # an edge from a vertex to itself
    assert is_closed(tetrahedron(10**15))  # sparse indices take the sorting path


def test_shells_are_numbered_by_their_first_triangle():
    faces = np.concatenate([tetrahedron(4), tetrahedron(0), tetrahedron(4)[:1]])
    label, count = shell_labels(faces, 8)
    assert count == 2 and label.tolist() == [0, 0, 0, 0, 1, 1, 1, 1, 0]
    with pytest.raises(ValueError, match="index out of range"):
        shell_labels(faces, 7)


def test_merging_groups_equal_rounded_coordinates_in_first_appearance_order():
    v = np.array([[1.0, 0, 0], [0, 0, 0], [1 + 4e-9, 0, 0], [0, 1, 0], [9, 9, 9], [1e-9, 0, 0]])
    f = np.array([[0, 1, 3], [2, 3, 5]])
    merged, faces = merge_vertices(v, f)
    assert merged.tolist() == [[1.0, 0, 0], [0, 0, 0], [0, 1, 0]]  # [9, 9, 9] is unused
    assert faces.tolist() == [[0, 1, 2], [0, 2, 1]]


def test_coordinates_beyond_int64_keys_are_compared_exactly():
    """At 1e11 (x * 1e8 leaves int64) trimesh's keys wrap and it merges distinct vertices."""
    v = np.array([[1e11, 0, 0], [2e11, 0, 0], [2e11, 1, 0], [1e11, 1, 1], [1e11, 0, 0]])
    f = np.array([[0, 1, 2], [4, 2, 3]])
    merged, faces = merge_vertices(v, f)
    assert merged.tolist() == v[:4].tolist()
    assert faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    # mixed magnitudes in one mesh: small coordinates still merge to 1e-8
    v2 = np.array([[1e11, 0, 0], [0, 1, 0], [0, 1 + 1e-9, 0]])
    assert len(merge_vertices(v2, np.array([[0, 1, 2]]))[0]) == 2


def test_degenerate_triangles_known_answers():
    v = [[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]
    repeated, flat = degenerate_triangles(v, [[0, 1, 3], [0, 1, 2], [3, 3, 3], [1, 0, 1]])
    assert repeated.tolist() == [False, False, True, True]
    assert flat.tolist() == [False, True, True, True]
    with pytest.raises(InputError, match="every triangle is degenerate"):
        clean_arrays(np.array(v), np.array([[0, 1, 2], [0, 0, 3]]), "flat.stl")


def test_loading_is_the_same_under_any_hash_seed(tmp_path):
    """Names and digests do not depend on PYTHONHASHSEED (no set or dict order decides them)."""
    for k in range(3):
        mesh = trimesh.creation.icosphere(subdivisions=1).apply_translation((3.0 * k, 0, 0))
        mesh.export(tmp_path / f"p{k}.stl")
    trimesh.util.concatenate(
        [trimesh.creation.box(), trimesh.creation.box().apply_translation((5, 0, 0))]
    ).export(tmp_path / "two.obj")
    code = (
        "import sys, meshcheck.load as L\n"
        "for b in L.load_bodies([sys.argv[1]], split=True): print(b.name, b.digest)\n"
    )
    runs = set()
    for seed in ("0", "1", "4242"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        out = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path)],
            capture_output=True,
            text=True,
            check=True,
            env=env,
        )
        runs.add(out.stdout)
    assert len(runs) == 1 and len(next(iter(runs)).splitlines()) == 5


# ---------------------------------------------------------------------------------------------
# Against independent oracles


@st.composite
def soups(draw):
    """Vertices drawn from a small lattice (so many repeat), some nudged by less than 1e-8 or
    by more, and faces over them."""
    n = draw(st.integers(3, 40))
    scale = draw(st.sampled_from([1e-3, 1.0, 1e3, 1e6]))
    lattice = draw(
        st.lists(st.tuples(*[st.integers(-3, 3)] * 3), min_size=n, max_size=n).map(np.array)
    )
    nudge = draw(
        st.lists(st.sampled_from([0.0, 1e-9, -3e-9, 4.9e-9, 5.1e-9, 2e-8, -0.0]), min_size=n)
    )
    v = lattice * scale
    v[:, 0] += np.resize(np.array(nudge), n)
    m = draw(st.integers(1, 30))
    f = draw(st.lists(st.tuples(*[st.integers(0, n - 1)] * 3), min_size=m, max_size=m))
    return v.astype(np.float64), np.array(f, dtype=np.int64)


@PROPERTY
@given(soups())
def test_merging_is_trimesh_merge_vertices(soup):
    """Same vertices in the same order and the same faces as trimesh's merge (tol.merge)."""
    v, f = soup
    mesh = trimesh.Trimesh(v, f, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    merged, faces = merge_vertices(v, f)
    np.testing.assert_array_equal(merged, mesh.vertices)
    np.testing.assert_array_equal(faces, mesh.faces)


@PROPERTY
@given(st.lists(st.tuples(st.integers(-2, 2), st.integers(0, 1)), min_size=0, max_size=60))
def test_group_rows_hashing_and_sorting_agree_with_numpy(rows):
    keys = np.array(rows, dtype=np.int64).reshape(-1, 2)
    first, inverse = group_rows(keys)
    first_sorted, inverse_sorted = group_rows(keys, by_sorting=True)
    np.testing.assert_array_equal(first, first_sorted)
    np.testing.assert_array_equal(inverse, inverse_sorted)
    _, index, oracle = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(index)  # numpy's groups renumbered by first appearance
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    np.testing.assert_array_equal(first, index[order])
    np.testing.assert_array_equal(inverse, rank[oracle.ravel()])


def _closed_oracle(faces: np.ndarray) -> bool:
    """The edge rule with numpy: each directed edge once, its reverse present."""
    if len(faces) == 0:
        return False
    tail = faces.ravel()
    head = faces[:, [1, 2, 0]].ravel()
    if np.any(tail == head):
        return False
    edges = {(int(a), int(b)) for a, b in zip(tail, head, strict=True)}
    return len(edges) == len(tail) and all((b, a) in edges for a, b in edges)


@st.composite
def edited_closed_meshes(draw):
    """Closed meshes (two kinds), then a few faces removed, flipped, repeated or rewired."""
    base = draw(st.sampled_from(["box", "sphere", "two"]))
    if base == "box":
        faces = np.asarray(trimesh.creation.box().faces)
    elif base == "sphere":
        faces = np.asarray(trimesh.creation.icosphere(subdivisions=1).faces)
    else:
        faces = np.concatenate([tetrahedron(0), tetrahedron(4)])
    faces = faces.copy()
    for _ in range(draw(st.integers(0, 2))):
        k = draw(st.integers(0, len(faces) - 1))
        edit = draw(st.sampled_from(["remove", "flip", "repeat", "rewire", "shuffle"]))
        if edit == "remove":
            faces = np.delete(faces, k, axis=0)
        elif edit == "flip":
            faces[k] = faces[k, ::-1]
        elif edit == "repeat":
            faces = np.concatenate([faces, faces[k : k + 1]])
        elif edit == "rewire":
            faces[k, draw(st.integers(0, 2))] = draw(st.integers(0, int(faces.max())))
        else:
            faces = faces[np.random.default_rng(k).permutation(len(faces))]
        if len(faces) == 0:
            break
    return faces.astype(np.int64)


@PROPERTY
@given(edited_closed_meshes())
def test_is_closed_agrees_with_the_edge_rule(faces):
    assert is_closed(faces) == _closed_oracle(faces)


@PROPERTY
@given(edited_closed_meshes(), st.integers(0, 5))
def test_shell_labels_agree_with_scipy(faces, spare):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = int(faces.max(initial=-1)) + 1 + spare
    label, count = shell_labels(faces, n)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, vertex_label = connected_components(graph, directed=False)
    oracle = vertex_label[faces[:, 0]]
    assert count == len(np.unique(oracle))
    # the same partition of the faces, numbered by first appearance
    for a in range(len(faces)):
        for b in range(a + 1, len(faces)):
            assert (label[a] == label[b]) == (oracle[a] == oracle[b])
    firsts = [int(np.flatnonzero(label == k)[0]) for k in range(count)]
    assert firsts == sorted(firsts)


@PROPERTY
@given(soups())
def test_degenerate_triangles_agree_with_numpy(soup):
    v, f = soup
    repeated, flat = degenerate_triangles(v, f)
    oracle_repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    np.testing.assert_array_equal(repeated, oracle_repeated)
    np.testing.assert_array_equal(flat, oracle_repeated | ~np.any(cross != 0.0, axis=1))
