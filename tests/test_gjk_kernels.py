"""The compiled kernels as a module: hostile arrays are refused, threads agree, nothing JITs."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from meshcheck.geometry import pack_convex, query_pairs
from meshcheck.geometry.triangles import (
    closest_points_on_triangles,
    pair_distances,
    point_distances,
    triangle_distance,
    winding_numbers,
)

CUBE = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
TRI = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
FACE = np.array([[0, 1, 2]], dtype=np.int64)


def test_importing_the_kernels_compiles_nothing():
    """The kernels are built at install: importing and running them loads no JIT compiler."""
    code = (
        "import sys, numpy as np; import meshcheck.geometry as g; "
        "g.signed_distance(np.eye(3), np.eye(3) + 2.0); "
        "print(sorted(m for m in ('numba', 'llvmlite') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def _pack():
    return pack_convex([CUBE, CUBE + 3.0])


@pytest.mark.parametrize(
    "field, value",
    [
        ("nbrs", np.array([99], dtype=np.int64)),  # a neighbour that is no vertex
        ("starts", np.array([0, 8, 4], dtype=np.int64)),  # shapes out of order
        ("starts", np.array([0, 8, 99], dtype=np.int64)),  # past the last vertex
        ("nbr_starts", np.zeros(3, dtype=np.int64)),  # wrong length
        ("lower", np.zeros((1, 3))),  # one box for two shapes
    ],
)
def test_query_pairs_refuses_a_malformed_pack(field, value):
    pack = _pack()
    if field == "nbrs":
        nbr_starts = pack.nbr_starts.copy()
        nbr_starts[1:] = 1
        pack = pack._replace(nbrs=value, nbr_starts=nbr_starts)
    else:
        pack = pack._replace(**{field: value})
    with pytest.raises(ValueError):
        query_pairs(pack, np.array([[0, 1]]), tolerance=1e-9)


def test_threads_zero_means_one_per_core_and_agrees():
    rng = np.random.default_rng(3)
    pack = pack_convex([rng.normal(size=(10, 3)) + rng.uniform(-3, 3, 3) for _ in range(30)])
    pairs = np.array([[i, j] for i in range(30) for j in range(i + 1, 30)], dtype=np.int64)
    one = query_pairs(pack, pairs, tolerance=1e-9, threads=1)
    every = query_pairs(pack, pairs, tolerance=1e-9, threads=0)
    for got, want in zip(every, one, strict=True):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    "call",
    [
        lambda: pair_distances(TRI, FACE + 1, TRI, FACE, np.zeros((1, 2), np.int64)),
        lambda: pair_distances(TRI, FACE, TRI, FACE, np.array([[0, 1]], np.int64)),
        lambda: winding_numbers(np.zeros((1, 3)), TRI, np.array([[0, 1, -1]])),
        lambda: point_distances(np.zeros((1, 3)), TRI, np.array([[0, 1, 3]])),
        lambda: closest_points_on_triangles(np.zeros(2), TRI, FACE),
    ],
)
def test_triangle_kernels_refuse_indices_out_of_range(call):
    with pytest.raises(ValueError):
        call()


def test_closest_point_on_a_flat_triangle_is_on_its_edges():
    """A zero-area triangle (three collinear corners) is measured by its edges."""
    v = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    dist, q = closest_points_on_triangles(np.array([1.5, 1.0, 0.0]), v, FACE)
    assert dist.tolist() == [1.0]
    assert q.tolist() == [[1.5, 0.0, 0.0]]
    # Its edge through another triangle still counts as crossing it; beside it, the gap.
    d, pa, _, crossing = triangle_distance(*v, [1.5, -1, -1], [1.5, 1, -1], [1.5, 0, 1])
    assert d == 0.0 and crossing and pa == (1.5, 0.0, 0.0)
    d, *_ = triangle_distance(*v, [1.5, 1, -1], [1.5, 2, -1], [1.5, 1, 1])
    assert d == 1.0
