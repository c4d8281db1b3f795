"""Convex pieces: every triangle covered, one decomposition per geometry, cached, deterministic."""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import Delaunay, QhullError

from meshcheck import decompose
from meshcheck.decompose import (
    coacd_options,
    cover_triangles,
    decompose_bodies,
    decompose_mesh,
    is_convex,
)
from meshcheck.load import Body

# Tiny, fast CoACD settings for tests (the defaults are tuned for 5,000-triangle parts).
FAST = {"resolution": 200, "mcts_nodes": 4, "mcts_iterations": 10, "mcts_max_depth": 1}
# In this process, so monkeypatched CoACD calls are seen.
SERIAL = {"jobs": 1, "time_limit": None}


def l_bracket() -> trimesh.Trimesh:
    a = trimesh.creation.box(bounds=[[0, 0, 0], [30, 20, 4]])
    b = trimesh.creation.box(bounds=[[0, 0, 4], [4, 20, 25]])
    return trimesh.boolean.union([a, b], engine="manifold")


def plate_with_hole() -> trimesh.Trimesh:
    plate = trimesh.creation.box(bounds=[[0, 0, 0], [20, 20, 3]])
    hole = trimesh.creation.cylinder(radius=4, height=5, sections=12)
    hole.apply_translation([10, 10, 1.5])
    return trimesh.boolean.difference([plate, hole], engine="manifold")


def u_channel() -> trimesh.Trimesh:
    base = trimesh.creation.box(bounds=[[0, 0, 0], [20, 10, 2]])
    left = trimesh.creation.box(bounds=[[0, 0, 2], [2, 10, 12]])
    right = trimesh.creation.box(bounds=[[18, 0, 2], [20, 10, 12]])
    return trimesh.boolean.union([base, left, right], engine="manifold")


def stairs() -> trimesh.Trimesh:
    steps = [
        trimesh.creation.box(bounds=[[0, 0, 0], [30 - 10 * k, 10, 5 * k + 5]]) for k in range(3)
    ]
    return trimesh.boolean.union(steps, engine="manifold")


MESHES = {"l_bracket": l_bracket, "plate_with_hole": plate_with_hole, "u_channel": u_channel}
# CoACD takes seconds on a plate with a hole even with FAST settings; these take a fraction.
COACD_MESHES = {"l_bracket": l_bracket, "stairs": stairs, "u_channel": u_channel}


def uncovered(vertices, faces, pieces, tol=1e-9) -> list[int]:
    """Triangles not inside any piece, by an independent oracle (Delaunay point location)."""
    vertices = np.asarray(vertices, float)
    scale = np.linalg.norm(np.ptp(vertices, axis=0))
    inside = np.zeros((len(vertices), len(pieces)), dtype=bool)
    for k, piece in enumerate(pieces):
        try:
            inside[:, k] = Delaunay(piece).find_simplex(vertices, tol=tol * scale) >= 0
        except QhullError:  # a flat piece holds no triangle here
            pass
    tri = inside[faces[:, 0]] & inside[faces[:, 1]] & inside[faces[:, 2]]
    return np.flatnonzero(~tri.any(axis=1)).tolist()


# ----------------------------------------------------------------------------- known answers


def test_convex_body_is_its_own_hull():
    box = trimesh.creation.box(extents=[1, 2, 3])
    assert is_convex(box)
    pieces = decompose_mesh(box.vertices, box.faces, coacd_options(**FAST))
    assert len(pieces) == 1
    assert sorted(map(tuple, pieces[0])) == sorted(map(tuple, box.vertices))


def test_concave_and_open_meshes_are_not_convex():
    assert not is_convex(l_bracket())
    open_box = trimesh.creation.box()
    open_box.update_faces(np.arange(len(open_box.faces)) != 0)
    assert not is_convex(open_box)


def test_cover_grows_a_partial_piece_to_the_whole_box():
    box = trimesh.creation.box()
    grown = cover_triangles(box.vertices, box.faces, [box.vertices[:4]])
    assert len(grown) == 1 and len(grown[0]) == 8
    assert uncovered(box.vertices, box.faces, grown) == []


def test_cover_with_no_pieces_returns_the_hull():
    mesh = l_bracket()
    pieces = cover_triangles(mesh.vertices, mesh.faces, [])
    assert len(pieces) == 1
    assert uncovered(mesh.vertices, mesh.faces, pieces) == []


def test_cover_keeps_pieces_that_already_cover():
    mesh = l_bracket()
    a = mesh.vertices[mesh.vertices[:, 2] <= 4]
    b = mesh.vertices[mesh.vertices[:, 0] <= 4]
    grown = cover_triangles(mesh.vertices, mesh.faces, [a, b])
    assert uncovered(mesh.vertices, mesh.faces, grown) == []
    assert [len(p) for p in grown] == [len(a), len(b)]


def test_cover_handles_a_flat_piece():
    mesh = l_bracket()
    flat = mesh.vertices[mesh.vertices[:, 2] == 0]
    grown = cover_triangles(mesh.vertices, mesh.faces, [flat])
    assert uncovered(mesh.vertices, mesh.faces, grown) == []


@pytest.mark.parametrize("name", sorted(COACD_MESHES))
def test_coacd_pieces_cover_every_triangle(name):
    mesh = COACD_MESHES[name]()
    pieces = decompose_mesh(mesh.vertices, mesh.faces, coacd_options(threshold=0.1, **FAST))
    assert len(pieces) >= 2
    assert uncovered(mesh.vertices, mesh.faces, pieces) == []
    # The pieces stay within the mesh's own hull (CoACD rounds to about float32 precision).
    hull = Delaunay(mesh.convex_hull.vertices)
    for piece in pieces:
        assert np.all(hull.find_simplex(piece, tol=1e-5) >= 0)


# ----------------------------------------------------------------------------- properties


@settings(derandomize=True, deadline=None, max_examples=40)
@given(
    name=st.sampled_from(sorted(MESHES)),
    seed=st.integers(0, 2**32 - 1),
    count=st.integers(1, 5),
    size=st.integers(4, 12),
)
def test_cover_property_random_pieces(name, seed, count, size):
    """Any starting pieces (random vertex subsets) end up covering every triangle, grown only."""
    mesh = MESHES[name]()
    rng = np.random.default_rng(seed)
    n = len(mesh.vertices)
    start = [mesh.vertices[rng.choice(n, size, replace=False)] for _ in range(count)]
    grown = cover_triangles(mesh.vertices, mesh.faces, [p.copy() for p in start])
    assert len(grown) == count
    assert uncovered(mesh.vertices, mesh.faces, grown) == []
    for before, after in zip(start, grown, strict=True):
        scale = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
        try:
            hull = Delaunay(after)
        except QhullError:  # a flat piece stays as it was
            assert np.array_equal(before, after)
            continue
        assert np.all(hull.find_simplex(before, tol=1e-9 * scale) >= 0)


@settings(derandomize=True, deadline=None, max_examples=20)
@given(
    offset=st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False)] * 3),
    angle=st.floats(0, 2 * np.pi),
)
def test_world_pieces_follow_the_body_transform(offset, angle):
    mesh = l_bracket()
    transform = trimesh.transformations.rotation_matrix(angle, [0.3, 0.2, 1.0])
    transform[:3, 3] = offset
    calls = []
    fake = [mesh.vertices[mesh.vertices[:, 2] <= 4], mesh.vertices[mesh.vertices[:, 0] <= 4]]

    def fake_coacd(m, **options):
        calls.append(1)
        return [p - mesh.vertices.min(axis=0) for p in fake]

    original = decompose.run_coacd
    decompose.run_coacd = fake_coacd
    try:
        (local,), (world,) = (
            decompose_bodies([Body("a", "a", mesh)], cache_dir=None, **SERIAL),
            decompose_bodies([Body("b", "b", mesh, transform)], cache_dir=None, **SERIAL),
        )
    finally:
        decompose.run_coacd = original
    assert len(local) == len(world) == 2
    for p, q in zip(local, world, strict=True):
        np.testing.assert_allclose(trimesh.transform_points(p, transform), q, atol=1e-9)
    moved = mesh.copy().apply_transform(transform)
    assert uncovered(moved.vertices, moved.faces, world, tol=1e-7) == []


# ----------------------------------------------------------------------------- once per geometry


@pytest.fixture
def counted(monkeypatch):
    """Count CoACD calls (jobs=1 without a time limit runs in this process)."""
    calls = []
    original = decompose.run_coacd

    def run(mesh, **options):
        calls.append(len(mesh.faces))
        return original(mesh, **options)

    monkeypatch.setattr(decompose, "run_coacd", run)
    return calls


def test_same_geometry_decomposed_once(counted):
    mesh = l_bracket()
    moved = mesh.copy().apply_translation([100.0, 50.0, 25.0])  # exact in float64 here
    nudged = mesh.copy()
    far = (mesh.vertices + np.array([1000.1, 0, 0])).astype(np.float32)
    nudged.vertices = far.astype(np.float64)
    shift = np.eye(4)
    shift[:3, 3] = [7, 0, 0]
    bodies = [
        Body("a", "a", mesh),
        Body("b", "b", moved),
        Body("c", "c", mesh, shift),  # an instance of the same mesh object
        Body("d", "d", nudged),  # float32 copy at another place: reuses the decomposition
    ]
    out = decompose_bodies(bodies, threshold=0.05, options=FAST, cache_dir=None, **SERIAL)
    assert len(counted) == 1
    assert len({len(p) for p in out}) == 1
    for body, pieces in zip(bodies, out, strict=True):
        world = body.world
        assert uncovered(world.vertices, world.faces, pieces, tol=1e-7) == []
    for p, q in zip(out[0], out[1], strict=True):
        np.testing.assert_allclose(p + np.array([100.0, 50.0, 25.0]), q, atol=1e-12)


def test_convex_bodies_skip_coacd(counted):
    box = trimesh.creation.box(extents=[1, 2, 3])
    out = decompose_bodies([Body("a", "a", box)], cache_dir=None, **SERIAL)
    assert counted == [] and len(out[0]) == 1


def test_no_pool_for_a_single_concave_mesh(monkeypatch, counted):
    import concurrent.futures

    def no_pool(*args, **kwargs):
        raise AssertionError("a process pool was started")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", no_pool)
    boxes = [trimesh.creation.box(extents=[1, k, 3]) for k in (1, 2, 3)]
    bodies = [Body(str(k), str(k), m) for k, m in enumerate([*boxes, l_bracket()])]
    out = decompose_bodies(bodies, options=FAST, cache_dir=None, jobs=4, time_limit=None)
    assert [len(p) == 1 for p in out] == [True, True, True, False]
    assert len(counted) == 1


def test_cache_round_trip_is_bit_exact_and_skips_coacd(tmp_path, counted):
    bodies = [Body("a", "a", l_bracket()), Body("b", "b", u_channel())]
    kwargs = {"threshold": 0.05, "options": FAST, "cache_dir": str(tmp_path), **SERIAL}
    cold = decompose_bodies(bodies, **kwargs)
    assert len(counted) == 2
    warm = decompose_bodies(bodies, **kwargs)
    assert len(counted) == 2
    for a, b in zip(cold, warm, strict=True):
        assert len(a) == len(b)
        assert all(x.tobytes() == y.tobytes() for x, y in zip(a, b, strict=True))
    # Another threshold is another entry.
    decompose_bodies(bodies[:1], **{**kwargs, "threshold": 0.2})
    assert len(counted) == 3


def test_corrupt_cache_entry_is_recomputed(tmp_path, counted):
    from meshcheck.cache import DecompositionCache

    bodies = [Body("a", "a", l_bracket())]
    kwargs = {"threshold": 0.05, "options": FAST, "cache_dir": str(tmp_path), **SERIAL}
    cold = decompose_bodies(bodies, **kwargs)
    cache = DecompositionCache(str(tmp_path))
    (entry,) = [p for p in (tmp_path.rglob("*.bin"))]
    entry.write_bytes(entry.read_bytes()[:100])
    again = decompose_bodies(bodies, **kwargs)
    assert len(counted) == 2
    assert all(x.tobytes() == y.tobytes() for x, y in zip(cold[0], again[0], strict=True))
    assert cache.get(entry.stem) is not None


def test_parallel_matches_serial(tmp_path):
    meshes = [l_bracket(), u_channel(), stairs()]
    bodies = [Body(str(k), str(k), mesh) for k, mesh in enumerate(meshes)]
    kwargs = {"threshold": 0.05, "options": FAST, "cache_dir": None}
    serial = decompose_bodies(bodies, jobs=1, time_limit=None, **kwargs)
    parallel = decompose_bodies(bodies, jobs=2, **kwargs)
    one_worker = decompose_bodies(bodies, jobs=1, time_limit=60.0, **kwargs)
    for a, b, c in zip(serial, parallel, one_worker, strict=True):
        assert len(a) == len(b) == len(c)
        assert all(x.tobytes() == y.tobytes() for x, y in zip(a, b, strict=True))
        assert all(x.tobytes() == y.tobytes() for x, y in zip(a, c, strict=True))


def test_overrunning_the_time_limit_falls_back_to_the_hull_and_says_so_on_progress(tmp_path):
    import warnings

    from meshcheck.progress import Progress

    mesh = l_bracket()
    stream = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # how the run went is no warning (it would reach reports)
        with Progress("decomposing", 1, stream=stream) as bar:
            (pieces,) = decompose_bodies(
                [Body("bracket.stl", "bracket.stl", mesh)],
                options={**FAST, "resolution": 5000, "mcts_iterations": 500},
                cache_dir=str(tmp_path),
                time_limit=1e-3,
                progress=bar,
            )
    assert len(pieces) == 1
    assert uncovered(mesh.vertices, mesh.faces, pieces) == []
    assert "meshcheck: bracket.stl: convex decomposition took over 0.001 s" in stream.getvalue()


def test_a_part_whose_pieces_do_not_pay_gets_its_hull_without_coacd(tmp_path, counted):
    mesh = l_bracket()
    body = Body("a", "a", mesh)
    digest = decompose.local_geometries([body])[id(mesh)].digest
    (pieces,) = decompose_bodies(
        [body], options=FAST, cache_dir=str(tmp_path), jobs=1, time_limit={digest: 0.0}
    )
    assert counted == [] and len(pieces) == 1
    assert uncovered(mesh.vertices, mesh.faces, pieces) == []
    assert not list(tmp_path.rglob("*.bin"))  # a hull that stood in is not a decomposition


def test_budgets_follow_the_work_the_pieces_would_save():
    """Few neighbours: CoACD does not pay. Many: it does, for at most the time it saves. Open
    meshes never go to CoACD."""
    plate = l_bracket()
    n = len(plate.faces)
    box = trimesh.creation.box()
    model = decompose.COST_MODEL
    per_pair = model.filter_share * model.verify_seconds(n, len(box.faces))
    enough = int(model.coacd_seconds(n) / per_pair) + 2
    for neighbours, pays in ((1, False), (enough, True)):
        bodies = [Body("plate", "plate", plate)]
        bodies += [Body(f"b{k}", f"b{k}", box.copy()) for k in range(neighbours)]
        pairs = np.array([[0, k + 1] for k in range(neighbours)])
        budgets = decompose.coacd_budgets(bodies, pairs)
        digest = decompose.local_geometries(bodies)[id(plate)].digest
        assert (budgets[digest] > 0) == pays
        if pays:
            assert budgets[digest] == pytest.approx(neighbours * per_pair)
        opened = Body("open", "open", trimesh.Trimesh(plate.vertices, plate.faces[1:]))
        budgets = decompose.coacd_budgets([opened, *bodies[1:]], pairs)
        assert budgets[decompose.local_geometries([opened])[id(opened.mesh)].digest] == 0.0


def test_progress_reports_every_mesh():
    from meshcheck.progress import Progress

    bodies = [Body("a", "a", l_bracket()), Body("b", "b", trimesh.creation.box())]
    with Progress("decomposing", 2, stream=io.StringIO()) as bar:
        decompose_bodies(bodies, options=FAST, cache_dir=None, jobs=1, progress=bar)
        assert bar.done == 2


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_draws_only_on_a_terminal():
    from meshcheck.progress import Progress

    pipe, tty = io.StringIO(), _Terminal()
    for stream in (pipe, tty):
        with Progress("decomposing", 2, stream=stream) as bar:
            bar.update(1)
            bar.update(2)
    assert pipe.getvalue() == ""
    assert "\rdecomposing 2/2" in tty.getvalue() and tty.getvalue().endswith("\r\033[K")


def test_near_copy_reuses_a_cached_decomposition(tmp_path, counted):
    mesh = l_bracket()
    copy = mesh.copy()
    copy.vertices = (mesh.vertices + np.array([500.3, 0, 0])).astype(np.float32).astype(np.float64)
    kwargs = {"threshold": 0.05, "options": FAST, "cache_dir": str(tmp_path), **SERIAL}
    decompose_bodies([Body("a", "a", mesh)], **kwargs)
    (out,) = decompose_bodies([Body("b", "b", copy)], **kwargs)
    assert len(counted) == 1
    assert uncovered(copy.vertices, copy.faces, out, tol=1e-7) == []
