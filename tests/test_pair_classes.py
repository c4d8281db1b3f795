"""Pair classes: an instanced assembly decided once per class, with the findings of deciding every
pair on its own; no verdict shared between pairs that differ (moved by more than the placement
grid, mirrored, another mesh, a forged cache entry).

The assemblies are modules of the sample's parts: a plate, three M6 bolts resting in its holes
(touching), an L-bracket standing on it (touching), and in planted modules the oversized bolt
pushed into the fourth hole (interference).
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import gltf_document, matrix_node

from meshcheck import pipeline
from meshcheck.cache import PairCache, pair_key, pair_secret
from meshcheck.errors import ExitStatus
from meshcheck.load import Body, local_geometries
from meshcheck.reports import render
from meshcheck.results import Verdict
from meshcheck.verify import batch, classes, verify_pair

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLES = os.path.join(ROOT, "sample_meshes")
HOLES = [(-35.0, -15.0), (-35.0, 15.0), (35.0, -15.0), (35.0, 15.0)]
HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=12)


def _sample(name: str, hole: tuple[float, float] | None = None) -> trimesh.Trimesh:
    """A sample part; a bolt moved so its axis is the frame's z axis."""
    mesh = trimesh.load_mesh(os.path.join(SAMPLES, name))
    if hole is not None:
        mesh.apply_translation([-hole[0], -hole[1], 0.0])
    return mesh


PLATE = _sample("plate.stl")
BOLT = _sample("bolt_m6_a.stl", HOLES[0])
FAT_BOLT = _sample("bolt_m8_oversized.stl", HOLES[3])
BRACKET = _sample("bracket.stl")


def turned(angle: float, at=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A rotation about z by ``angle`` degrees, then a move to ``at``."""
    m = trimesh.transformations.rotation_matrix(np.radians(angle), (0, 0, 1))
    m[:3, 3] = at
    return m


def shifted(x: float, y: float, z: float = 0.0) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def module(k: int, frame: np.ndarray, *, planted: bool = False, bolt=None) -> list[Body]:
    """Module ``k``'s parts at ``frame``; ``bolt`` replaces bolt 0's local placement."""
    parts = [Body(f"m{k}/plate", "plant.glb", PLATE, frame)]
    for h, (x, y) in enumerate(HOLES[:3]):
        local = shifted(x, y) if (h or bolt is None) else bolt
        parts.append(Body(f"m{k}/bolt{h}", "plant.glb", BOLT, frame @ local))
    parts.append(Body(f"m{k}/bracket", "plant.glb", BRACKET, frame))
    if planted:
        parts.append(Body(f"m{k}/fat", "plant.glb", FAT_BOLT, frame @ shifted(*HOLES[3])))
    return parts


def plant() -> list[Body]:
    """Six modules: moved, turned (also off the axes), two with the oversized bolt."""
    frames = [
        shifted(0.0, 0.0),
        shifted(300.0, 0.0),
        turned(90.0, (0.0, 300.0, 0.0)),
        turned(180.0, (300.0, 300.0, 0.0)),
        turned(33.0, (600.0, 0.0, 0.0)),
        turned(33.0, (600.0, 300.0, 5.0)),
    ]
    return [b for k, f in enumerate(frames) for b in module(k, f, planted=k in (1, 4))]


def each_pair_alone(monkeypatch) -> None:
    """Make every pair its own class, its placement computed from that pair alone."""
    real = classes.pair_classes

    def alone(bodies, pairs, tolerance, surfaces_apart=None, *, geometry):
        parts = [
            real(
                bodies,
                pairs[k : k + 1],
                np.asarray(tolerance)[k : k + 1],
                None if surfaces_apart is None else np.asarray(surfaces_apart)[k : k + 1],
                geometry=geometry,
            )
            for k in range(len(pairs))
        ]
        whole = real(bodies, pairs, tolerance, surfaces_apart, geometry=geometry)
        k = len(parts)
        return dataclasses.replace(
            whole,
            pairs=np.concatenate([p.pairs for p in parts]).reshape(-1, 2),
            label=np.arange(k),
            first=np.arange(k),
            placed=[p.placed[0] for p in parts],
            tolerance=np.array([p.tolerance[0] for p in parts]),
            surfaces_apart=np.array([p.surfaces_apart[0] for p in parts], dtype=bool),
        )

    monkeypatch.setattr(pipeline, "pair_classes", alone)


def check(bodies, **options):
    return pipeline.check_bodies(bodies, cache_dir=None, jobs=1, **options)


def same_findings(one, other) -> None:
    """Every field of every finding equal, the shared solids and closest points to the bit."""
    assert [(f.a, f.b, f.id, f.tolerance, f.pattern) for f in one] == [
        (f.a, f.b, f.id, f.tolerance, f.pattern) for f in other
    ]
    for f, g in zip(one, other, strict=True):
        assert f.verdict == g.verdict, (f.a, f.b)
        for mine, theirs in ((f.solid, g.solid), (f.closest, g.closest)):
            assert (mine is None) == (theirs is None)
        if f.solid is not None:
            assert f.solid.vertices.tobytes() == g.solid.vertices.tobytes()
            assert f.solid.faces.tobytes() == g.solid.faces.tobytes()
        if f.closest is not None:
            pairs = zip(f.closest, g.closest, strict=True)
            assert all(p.tobytes() == q.tobytes() for p, q in pairs)


def world_oracle(bodies, finding):
    """The pair decided on its world meshes, as the verify stage once did."""
    by_name = {b.name: b for b in bodies}
    a, b = by_name[finding.a], by_name[finding.b]
    return verify_pair(a.world, b.world, tolerance=finding.tolerance, clearance=None)


# ------------------------------------------------------------------------------------------
# Known answers


def test_an_instanced_plant_is_decided_once_per_class_as_if_pair_by_pair(counted, monkeypatch):
    bodies = plant()
    result = check(bodies)
    by_class = len(counted)
    statuses = [str(f.status) for f in result.findings]
    assert statuses.count("interference") == 2 and statuses.count("touching") == 24

    each_pair_alone(monkeypatch)
    alone = check(bodies)
    # every pair that comes near, one by one: twice the work at least (modules in three
    # float32 binades get three tolerances, so six modules make three copies of each class)
    assert len(counted) - by_class >= 2 * by_class
    same_findings(result.findings, alone.findings)

    for f in result.findings:  # and each agrees with the pair decided on its world meshes
        oracle = world_oracle(bodies, f)
        assert oracle.status == f.status, (f.a, f.b)
        assert f.distance == pytest.approx(oracle.distance, abs=1e-9)
        if f.depth is not None:
            assert f.depth == pytest.approx(oracle.depth, rel=1e-6)
            assert f.volume == pytest.approx(oracle.volume, rel=1e-6)
        assert np.allclose(f.location.centroid, oracle.location.centroid, atol=1e-6)


def test_pairs_of_one_class_sit_within_the_placement_grid_of_each_other():
    bodies = plant()
    geometry = local_geometries(bodies)
    index = {b.name: k for k, b in enumerate(bodies)}
    result = check(bodies)
    pairs = np.array([[index[f.a], index[f.b]] for f in result.findings])
    tol = np.array([f.tolerance for f in result.findings])
    found = classes.pair_classes(bodies, pairs, tol, geometry=geometry)
    for rows in found.members():
        if len(rows) < 2:
            continue
        i0, j0 = found.pairs[rows[0]]
        for k in rows[1:]:
            i, j = found.pairs[k]
            moved = _max_vertex_move(bodies, geometry, (i0, j0), (i, j))
            grid = classes._grid(tol[rows[0]])
            assert moved <= 2.4 * grid + 1e-12 * 600, (bodies[i].name, bodies[j].name)


def _max_vertex_move(bodies, geometry, first, second) -> float:
    """How far the second part of ``second`` sits from where the second part of ``first``
    sits, each in its first part's frame: the largest move of a vertex."""
    placed = []
    for i, j in (first, second):
        frame_i = np.asarray(bodies[i].transform) @ shifted(*geometry[id(bodies[i].mesh)].corner)
        frame_j = np.asarray(bodies[j].transform) @ shifted(*geometry[id(bodies[j].mesh)].corner)
        local = geometry[id(bodies[j].mesh)].local
        relative = np.linalg.solve(frame_i, frame_j)
        placed.append(local @ relative[:3, :3].T + relative[:3, 3])
    return float(np.abs(placed[0] - placed[1]).max())


def test_a_class_decided_at_its_first_pairs_world_placement_moves_to_its_members():
    # The recipe the classes module gives another decision procedure (the B-rep stage): decide
    # a class on its first pair where it is, take the verdict into the class's frame, move it
    # to every member. The members get their own verdicts to within the placement rounding.
    bodies = plant()
    geometry = local_geometries(bodies)
    result = check(bodies)
    index = {b.name: k for k, b in enumerate(bodies)}
    pairs = np.array([[index[f.a], index[f.b]] for f in result.findings])
    tolerance = np.array([f.tolerance for f in result.findings])
    found = classes.pair_classes(bodies, pairs, tolerance, geometry=geometry)
    by_pair = {(f.a, f.b): f for f in result.findings}
    for c, rows in enumerate(found.members()):
        first = found.first[c]
        i, j = found.pairs[first]
        here = verify_pair(
            bodies[i].world, bodies[j].world, tolerance=found.tolerance[c], clearance=None
        )
        in_frame = classes.unplaced_verdict(here, *found.frame(first))
        for k, moved in zip(
            rows, classes.placed_verdicts(in_frame, *found.frames(rows)), strict=True
        ):
            a, b = sorted((bodies[found.pairs[k, 0]].name, bodies[found.pairs[k, 1]].name))
            own = by_pair[a, b]
            assert moved.status == own.status
            assert np.allclose(moved.location.centroid, own.location.centroid, atol=1e-6)
            if own.depth is not None:
                assert moved.depth == pytest.approx(own.depth, rel=1e-6)
    # ... and a verdict taken into a frame and back is where it was
    rotation, origin = found.frame(0)
    back = classes.placed_verdict(
        classes.unplaced_verdict(here, rotation, origin), rotation, origin
    )
    assert np.allclose(back.location.centroid, here.location.centroid, atol=1e-9)


# ------------------------------------------------------------------------------------------
# Properties: a moved instance is decided as itself


@HYPOTHESIS
@given(
    fraction=st.one_of(st.floats(0.0, 0.95), st.floats(1.05, 3.0)),
    down=st.booleans(),
    angle=st.floats(0.0, 360.0),
    at=st.tuples(st.floats(-500.0, 500.0), st.floats(-500.0, 500.0)),
)
def test_an_instance_moved_by_less_or_more_than_the_tolerance_is_decided_as_itself(
    fraction, down, angle, at
):
    tol = 2.3e-4  # given, so every module's pairs have it wherever they are
    dz = (-1.0 if down else 1.0) * fraction * tol
    frames = [turned(angle, (at[0] + 300.0 * k, at[1], 0.0)) for k in range(3)]
    bodies = [
        b
        for k, f in enumerate(frames)
        for b in module(k, f, bolt=shifted(*HOLES[0], dz) if k == 1 else None)
    ]
    with pytest.MonkeyPatch.context() as mp:
        calls = []
        real = batch.verify_pair
        mp.setattr(batch, "verify_pair", lambda a, b, **kw: calls.append(1) or real(a, b, **kw))
        together = check(bodies, tolerance=tol)
        each_pair_alone(mp)
        alone = check(bodies, tolerance=tol)
    same_findings(together.findings, alone.findings)

    moved = {(f.a, f.b): f for f in together.findings}.get(("m1/bolt0", "m1/plate"))
    if dz > tol:  # lifted off by more than the tolerance: clear
        assert moved is None
    elif dz < -tol:  # pushed in by more: an interference, never the others' touching
        assert moved is not None and moved.status == Verdict.INTERFERENCE
        assert moved.depth == pytest.approx(-dz, rel=0.05)
    else:
        assert moved is not None and moved.status == Verdict.TOUCHING
    # three modules, four situations each; the moved bolt is its own when it left the grid cell
    by_class = len(calls) - len(together.checked_pairs)
    grid = classes._grid(np.array([tol]))[0]
    if abs(dz) > 2.0 * grid:
        assert by_class == 5
    else:
        assert by_class in (4, 5)


# ------------------------------------------------------------------------------------------
# Pairs that differ never share a verdict


KEY = trimesh.creation.box(extents=(10.0, 10.0, 4.0)).apply_translation((5.0, 0.0, 12.0))
POST = trimesh.creation.box(extents=(6.0, 6.0, 20.0)).apply_translation((-5.0, 0.0, 20.0))


def keyed_module(k: int, frame: np.ndarray, *, mirrored: bool) -> list[Body]:
    """A plate, a key lying on it (x from 0 to 10) and a post beside it (x from -8 to -2); the
    key mirrored across the plate's x = 0 lies on the post's side, through it."""
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0]) if mirrored else np.eye(4)
    return [
        Body(f"m{k}/plate", "plant.glb", PLATE, frame),
        Body(f"m{k}/key", "plant.glb", KEY, frame @ mirror),
        Body(f"m{k}/post", "plant.glb", POST, frame),
    ]


def test_a_mirrored_instance_is_its_own_class(counted):
    bodies = keyed_module(0, np.eye(4), mirrored=False)
    plain = check(bodies)
    plain_calls = len(counted)
    bodies += keyed_module(1, shifted(0.0, 300.0), mirrored=True)
    both = check(bodies)
    found = {(f.a, f.b): f for f in both.findings}
    assert ("m0/key", "m0/post") not in found  # 2 apart
    assert found["m1/key", "m1/post"].status == Verdict.INTERFERENCE
    assert found["m1/key", "m1/plate"].status == Verdict.TOUCHING
    # the mirrored key on its plate is decided again, not given the plain key's verdict
    assert len(counted) - plain_calls > plain_calls
    for f in both.findings:
        assert world_oracle(bodies, f).status == f.status
    mirrored = found["m1/key", "m1/plate"].location.centroid
    assert mirrored[0] == pytest.approx(-found["m0/key", "m0/plate"].location.centroid[0])
    assert [(f.a, f.b) for f in plain.findings] == [("m0/key", "m0/plate"), ("m0/plate", "m0/post")]


def test_an_instance_with_a_changed_mesh_is_its_own_class(counted):
    sunk = BOLT.copy()
    head = sunk.vertices[:, 2] > 9.99  # the head, resting on the plate at z = 10
    sunk.vertices[head, 2] -= 0.01  # 0.01 into the plate: 40 tolerances
    bodies = module(0, np.eye(4))
    other = module(1, shifted(300.0, 0.0))
    other[1] = Body("m1/bolt0", "plant.glb", sunk, other[1].transform)
    bodies += other
    result = check(bodies)
    found = {(f.a, f.b): f for f in result.findings}
    assert found["m0/bolt0", "m0/plate"].status == Verdict.TOUCHING
    assert found["m1/bolt0", "m1/plate"].status == Verdict.INTERFERENCE
    assert found["m1/bolt0", "m1/plate"].depth == pytest.approx(0.01, rel=0.05)


def test_a_forged_entry_claiming_a_class_is_a_miss(tmp_path):
    bodies = module(0, np.eye(4), planted=True) + module(1, shifted(300.0, 0.0), planted=True)
    cache_dir = tmp_path / "cache"
    cold = pipeline.check_bodies(bodies, cache_dir=cache_dir, jobs=1)
    assert [str(f.status) for f in cold.findings].count("interference") == 2
    key, clear_key = _class_keys(bodies, cold, cache_dir)
    cache = PairCache(cache_dir, secret=pair_secret())
    entry = cache.path(key)
    original = open(entry).read()

    forger = PairCache(tmp_path / "forger", secret=b"a guess" * 5)
    forger.put(key, dataclasses.replace(cold.findings[0].verdict, status=Verdict.CLEAR))
    with open(forger.path(key)) as f:
        forgeries = [f.read()]  # signed with another key
    with open(cache.path(clear_key)) as f:
        forgeries.append(f.read())  # a genuine entry of another class, moved to this one's place
    claimed = json.loads(forgeries[-1])
    claimed["key"] = key
    forgeries.append(json.dumps(claimed))  # ... and made to claim this class
    for forged in forgeries:
        with open(entry, "w") as f:
            f.write(forged)
        warm = pipeline.check_bodies(bodies, cache_dir=cache_dir, jobs=1)
        assert render(warm, "json") == render(cold, "json")
    with open(entry) as f:
        assert f.read() == original  # the miss was verified again and stored


def _class_keys(bodies, result, cache_dir) -> tuple[str, str]:
    """The cache keys of the interfering class and of a class that is clear."""
    index = {b.name: k for k, b in enumerate(bodies)}
    geometry = local_geometries(bodies)
    (clash, *_) = [f for f in result.findings if f.status == Verdict.INTERFERENCE]
    pair = np.array([[index[clash.a], index[clash.b]], [index["m0/bolt0"], index["m0/bolt1"]]])
    found = classes.pair_classes(bodies, pair, [clash.tolerance] * 2, geometry=geometry)
    keys = []
    for c in range(2):
        a, b, tol, apart = classes.class_identity(found, c)
        keys.append(pair_key(a, b, tolerance=tol, clearance=None, surfaces_apart=apart))
    cache = PairCache(cache_dir, secret=pair_secret())
    if not os.path.exists(cache.path(keys[1])):  # the bolts' pair is not verified: sign one
        cache.put(keys[1], dataclasses.replace(clash.verdict, status=Verdict.CLEAR))
    return keys[0], keys[1]


# ------------------------------------------------------------------------------------------
# One report however the run goes


def plant_gltf(path) -> str:
    """The plant as a glTF: one mesh per part, a node per module, its parts as children."""
    meshes = {"plate": PLATE, "bolt": BOLT, "fat": FAT_BOLT, "bracket": BRACKET}
    frames = [shifted(0.0, 0.0), turned(90.0, (300.0, 0.0, 0.0)), turned(33.0, (0.0, 300.0, 0))]
    frames += [turned(180.0, (300.0 * k, 600.0, 0.0)) for k in range(3)]
    nodes = []
    for k, frame in enumerate(frames):
        children = [len(nodes) + 1 + c for c in range(5 + (k % 3 == 1))]
        nodes.append(matrix_node(frame, name=f"m{k}", children=children))
        nodes.append({"name": f"m{k}/plate", "mesh": "plate"})
        for h, (x, y) in enumerate(HOLES[:3]):
            nodes.append({"name": f"m{k}/bolt{h}", "mesh": "bolt", "translation": [x, y, 0.0]})
        nodes.append({"name": f"m{k}/bracket", "mesh": "bracket"})
        if k % 3 == 1:
            nodes.append({"name": f"m{k}/fat", "mesh": "fat", "translation": [*HOLES[3], 0.0]})
    with open(path, "w") as f:
        json.dump(gltf_document(meshes, nodes), f)
    return str(path)


def test_reports_are_identical_cold_warm_and_in_workers(tmp_path, monkeypatch):
    path = plant_gltf(tmp_path / "plant.gltf")
    units = {path: "mm"}

    def report(cache, jobs):
        result = pipeline.check([path], config=None, cache_dir=cache, jobs=jobs, file_units=units)
        return render(result, "json")

    serial = report(None, 1)
    cold = report(tmp_path / "c1", 1)
    warm = report(tmp_path / "c1", 1)
    monkeypatch.setattr(batch, "POOL_SECONDS", 0.0)
    monkeypatch.setattr(batch, "PAIRS_PER_TASK", 1)
    monkeypatch.setattr(batch, "VERIFY_HERE_TOO", False)
    workers_cold = report(tmp_path / "c2", 2)
    workers_warm = report(tmp_path / "c2", 2)
    serial_warm = report(tmp_path / "c2", 1)
    assert serial == cold == warm == workers_cold == workers_warm == serial_warm
    statuses = [r["status"] for r in json.loads(serial)["results"]]
    assert statuses.count("interference") == 2 and statuses.count("touching") == 24


def test_moving_the_whole_plant_reuses_every_verdict(tmp_path, counted):
    bodies = plant()
    pipeline.check_bodies(bodies, cache_dir=tmp_path / "c", tolerance=2.3e-4, jobs=1)
    verified = len(counted)
    far = shifted(4096.0, -2048.0)
    away = [dataclasses.replace(b, transform=far @ b.transform) for b in bodies]
    moved = pipeline.check_bodies(away, cache_dir=tmp_path / "c", tolerance=2.3e-4, jobs=1)
    assert len(counted) == verified > 0  # every class found in the cache
    fresh = pipeline.check_bodies(away, cache_dir=None, tolerance=2.3e-4, jobs=1)
    same_findings(moved.findings, fresh.findings)


# ------------------------------------------------------------------------------------------
# From the command line, as an attacker with a pull request would try


def _run(args, **kw):
    from test_hostile_inputs_more import run

    return run(args, seconds=60, memory=2 << 30, **kw)


def _pushed_gltf(path, *, mirrored=False, sunk=0.0, changed=False) -> str:
    """Ten modules of a plate and a key; in module 7 the key is pushed ``sunk`` into the
    plate, or mirrored onto the post, or another mesh (the same key, one corner pulled in)."""
    key = KEY.copy()
    if changed:
        key.vertices[np.argmin(key.vertices.sum(axis=1))] += (0.0, 0.0, -0.05)
    meshes = {"plate": PLATE, "key": KEY, "post": POST, "changed": key}
    nodes = []
    for k in range(10):
        is_odd = k == 7
        children = [len(nodes) + 1, len(nodes) + 2, len(nodes) + 3]
        nodes.append(matrix_node(shifted(300.0 * k, 0.0), name=f"m{k}", children=children))
        nodes.append({"name": f"m{k}/plate", "mesh": "plate"})
        placement = np.eye(4)
        if is_odd and mirrored:
            placement = np.diag([-1.0, 1.0, 1.0, 1.0])
        if is_odd and sunk:
            placement = shifted(0.0, 0.0, -sunk)
        mesh = "changed" if (is_odd and changed) else "key"
        nodes.append(matrix_node(placement, name=f"m{k}/key", mesh=mesh))
        nodes.append({"name": f"m{k}/post", "mesh": "post"})
    with open(path, "w") as f:
        json.dump(gltf_document(meshes, nodes), f)
    return str(path)


@pytest.mark.posix_only
@pytest.mark.parametrize(
    "variant",
    [{"sunk": 2.3e-4 * 1.2}, {"mirrored": True}, {"changed": True}],
    ids=["moved-just-over-the-tolerance", "mirrored", "changed-mesh"],
)
def test_one_instance_that_differs_fails_the_run(tmp_path, variant):
    path = _pushed_gltf(tmp_path / "keys.gltf", **variant)
    status, out, lines = _run(
        [path, "--units", f"{path}=mm", "--tolerance", "2.3e-4", "--format", "json"]
    )
    assert status == ExitStatus.FAILED, lines
    results = json.loads(out)["results"]
    failing = [(r["a"], r["b"]) for r in results if r["status"] == "interference"]
    assert failing and all("#m7/" in a and "#m7/" in b for a, b in failing), failing
    assert [r["status"] for r in results].count("touching") >= 9


@pytest.mark.posix_only
def test_a_forged_cache_entry_does_not_pass_the_run(tmp_path):
    path = _pushed_gltf(tmp_path / "keys.gltf", sunk=0.01)
    args = [path, "--units", f"{path}=mm", "--cache-dir", tmp_path / "cache"]
    env = {"MESHCHECK_CACHE_SECRET": "the CI's own"}
    status, _, lines = _run(args, cache=True, env=env)
    assert status == ExitStatus.FAILED, lines
    for entry in (tmp_path / "cache").rglob("*.json"):  # every verdict forged clear, unsigned
        doc = json.loads(entry.read_text())
        doc["verdict"] = {**doc["verdict"], "status": "clear", "location": None}
        entry.write_text(json.dumps(doc))
    status, _, lines = _run(args, cache=True, env=env)
    assert status == ExitStatus.FAILED, lines
