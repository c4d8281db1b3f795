"""Pair verdicts: cached and reused only for the same pair class (meshes, placement in the pair's
frame, settings); the output does not depend on where a verdict came from (cache, this process,
-j workers); a forged entry cannot turn a failing check into a pass."""

from __future__ import annotations

import base64
import json
import os
import shutil
import stat
import zlib

import numpy as np
import pytest
import trimesh

from meshcheck import pipeline
from meshcheck.cache import PairCache, pair_key, pair_secret
from meshcheck.cache import verdicts as verdicts_module
from meshcheck.errors import MeshcheckWarning
from meshcheck.load import local_geometries
from meshcheck.reports import render
from meshcheck.results import PairVerdict, Solid, Verdict
from meshcheck.verify import batch, verify_pair
from meshcheck.verify.classes import class_identity, pair_classes


def write_row(directory, moved: float = 0.0) -> list[str]:
    """Ten 10 mm boxes in a row: 0-1 interfere by 1 mm, 1-2 touch, 2-3 0.3 mm apart, the others
    1 mm apart (clear at the clearance of 0.5 used here) but 8-9 touch; box 9 is shifted by
    ``moved`` along y."""
    os.makedirs(directory, exist_ok=True)
    x = [0.0, 9.0, 19.0, 29.3]
    while len(x) < 9:
        x.append(x[-1] + 11.0)
    x.append(x[-1] + 10.0)
    paths = []
    for k, xk in enumerate(x):
        box = trimesh.creation.box(extents=[10, 10, 10])
        box.apply_translation([xk, moved if k == 9 else 0.0, 0.0])
        path = os.path.join(directory, f"box{k}.stl")
        box.export(path)
        paths.append(path)
    return paths


def run(paths, cache_dir, **options):
    options.setdefault("config", None)
    result = pipeline.check(paths, cache_dir=cache_dir, clearance=0.5, **options)
    return result, render(result, "json")


def test_unchanged_rerun_verifies_nothing_and_output_is_identical(tmp_path, counted):
    paths = write_row(tmp_path / "row")
    cold, cold_json = run(paths, tmp_path / "c", jobs=1)
    verified = len(counted)
    # boxes 1-2 and 8-9 touch alike: one class, verified once
    assert verified == len(cold.checked_pairs) - 1 == 3
    warm, warm_json = run(paths, tmp_path / "c", jobs=1)
    assert len(counted) == verified  # nothing verified again
    assert warm_json == cold_json
    assert [str(f.status) for f in warm.findings] == [
        "interference",
        "touching",
        "clearance",
        "touching",
    ]


def test_after_one_part_moves_only_its_pairs_are_verified(tmp_path, counted):
    run(write_row(tmp_path / "row"), tmp_path / "c", jobs=1)
    before = len(counted)
    moved, moved_json = run(write_row(tmp_path / "row", moved=0.5), tmp_path / "c", jobs=1)
    with_box9 = [p for p in moved.checked_pairs if any(n.endswith("box9.stl") for n in p)]
    assert len(counted) - before == len(with_box9) == 1
    _, fresh_json = run(write_row(tmp_path / "row", moved=0.5), None, use_cache=False, jobs=1)
    assert moved_json == fresh_json


def test_argument_order_changes_neither_verdicts_nor_cache_hits(tmp_path, counted):
    paths = write_row(tmp_path / "row")
    _, forward = run(paths, tmp_path / "c", jobs=1)
    verified = len(counted)
    _, backward = run(paths[::-1], tmp_path / "c", jobs=1)
    assert len(counted) == verified  # every verdict found under the same key
    _, fresh = run(paths[::-1], None, use_cache=False, jobs=1)
    assert len(counted) == 2 * verified
    results = [json.loads(report)["results"] for report in (forward, backward, fresh)]
    assert results[0] == results[1] == results[2]  # every number, to the last bit


def test_parallel_verify_is_byte_identical_to_serial(tmp_path, monkeypatch, counted):
    monkeypatch.setattr(batch, "POOL_SECONDS", 0.0)
    monkeypatch.setattr(batch, "PAIRS_PER_TASK", 2)
    paths = write_row(tmp_path / "row")
    _, serial = run(paths, None, use_cache=False, jobs=1)
    serial_count = len(counted)
    monkeypatch.setattr(batch, "VERIFY_HERE_TOO", False)
    _, parallel_cold = run(paths, tmp_path / "c", jobs=2)
    assert len(counted) == serial_count  # verified in the worker processes, not here
    _, parallel_warm = run(paths, tmp_path / "c", jobs=2)
    _, serial_warm = run(paths, tmp_path / "c", jobs=1)
    monkeypatch.setattr(batch, "VERIFY_HERE_TOO", True)  # this process and one worker
    _, beside = run(paths, None, use_cache=False, jobs=2)
    assert serial == parallel_cold == parallel_warm == serial_warm == beside
    assert len(json.loads(serial)["results"]) == 4


def _interfering_pair_key(paths, cache_dir):
    """Key of the box0-box1 pair's class as the pipeline computes it."""
    result, _ = run(paths, cache_dir, jobs=1)
    (finding,) = [f for f in result.findings if str(f.status) == "interference"]
    index = {b.name: k for k, b in enumerate(result.bodies)}
    pair = np.array([[index[finding.a], index[finding.b]]])
    geometry = local_geometries(result.bodies)
    classes = pair_classes(result.bodies, pair, [finding.tolerance], [False], geometry=geometry)
    a, b, tol, apart = class_identity(classes, 0)
    return pair_key(a, b, tolerance=tol, clearance=0.5, surfaces_apart=apart)


CLEAR = PairVerdict(Verdict.CLEAR, float("inf"))


def test_a_forged_clear_entry_cannot_turn_fail_into_pass(tmp_path):
    paths = write_row(tmp_path / "row")
    key = _interfering_pair_key(paths, tmp_path / "c")
    # An attacker who can write the cache but does not hold the key signs with another one
    # and puts the entry where the run's own entry is (the only file in the cache).
    entry_path = PairCache(tmp_path / "c", secret=pair_secret()).path(key)
    assert os.path.exists(entry_path)
    forger = PairCache(tmp_path / "forger", secret=b"guessed" * 5)
    forger.put(key, CLEAR)
    shutil.copyfile(forger.path(key), entry_path)
    result, _ = run(paths, tmp_path / "c", jobs=1)
    assert not result.passed
    assert "interference" in [str(f.status) for f in result.findings]
    # ... and an entry with the signature stripped, or garbage, is a miss too.
    with open(entry_path) as f:
        entry = json.load(f)
    for forged in ({**entry, "mac": ""}, {"key": key}, "garbage", {**entry, "verdict": None}):
        with open(entry_path, "w") as f:
            f.write(forged if isinstance(forged, str) else json.dumps(forged))
        result, _ = run(paths, tmp_path / "c", jobs=1)
        assert not result.passed


def test_the_key_holder_is_the_trust_boundary(tmp_path):
    # The same forged verdict signed with the real key is used: the signature is what stands
    # between the cache and the verdict, so the test above would fail without it.
    paths = write_row(tmp_path / "row")
    key = _interfering_pair_key(paths, tmp_path / "c")
    PairCache(tmp_path / "c", secret=pair_secret()).put(key, CLEAR)
    result, _ = run(paths, tmp_path / "c", jobs=1)
    assert "interference" not in [str(f.status) for f in result.findings]


def test_runs_with_different_keys_keep_each_others_verdicts(tmp_path, counted, monkeypatch):
    paths = write_row(tmp_path / "row")
    run(paths, tmp_path / "c", jobs=1)
    verified = len(counted)
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "another key")
    run(paths, tmp_path / "c", jobs=1)  # verifies everything, signs with its key
    assert len(counted) == 2 * verified
    monkeypatch.delenv("MESHCHECK_CACHE_SECRET")
    run(paths, tmp_path / "c", jobs=1)  # the first key's entries are still there
    assert len(counted) == 2 * verified


@pytest.mark.posix_only
def test_the_key_file_is_private_and_outside_the_cache(tmp_path):
    secret = pair_secret()
    state = os.environ["XDG_STATE_HOME"]
    path = os.path.join(state, "meshcheck", "cache-secret")
    assert len(secret) == 32 and stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert pair_secret() == secret  # created once
    os.chmod(path, 0o644)
    try:
        with pytest.warns(MeshcheckWarning, match="not private"):
            assert pair_secret() is None
    finally:
        os.chmod(path, 0o600)


def test_the_environment_secret_wins(monkeypatch):
    from_file = pair_secret()
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "from-ci")
    a = pair_secret()
    assert a != from_file
    monkeypatch.setenv("MESHCHECK_CACHE_SECRET", "other")
    assert a != pair_secret()


def _solid_verdict() -> PairVerdict:
    a = trimesh.creation.box(extents=[1, 1, 1])
    b = trimesh.creation.box(extents=[1, 1, 1]).apply_translation([0.7, 0.1, 0.05])
    return verify_pair(a, b, tolerance=1e-6, clearance=None)


def test_a_verdict_comes_back_bit_for_bit_with_its_solid_and_closest_points(tmp_path):
    cache = PairCache(tmp_path, secret=b"k")
    clash = _solid_verdict()
    assert clash.solid is not None and len(clash.solid.faces) >= 12
    p, q = np.array([0.1, 1e-17, -3.0]), np.array([0.3, 2.0, np.nextafter(-3.0, 0)])
    near = PairVerdict(Verdict.CLEARANCE, 0.2, closest=(p, q))
    for key, verdict in (("ab" * 32, clash), ("cd" * 32, near)):
        cache.put(key, verdict)
        got = cache.get(key)
        assert got == verdict
        for mine, theirs in ((got.solid, verdict.solid), (got.closest, verdict.closest)):
            if theirs is None:
                assert mine is None
                continue
            mine = (mine.vertices, mine.faces) if hasattr(mine, "faces") else mine
            theirs = (theirs.vertices, theirs.faces) if hasattr(theirs, "faces") else theirs
            for x, y in zip(mine, theirs, strict=True):
                assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def _solid_field(*, extra=b"", **fields):
    """A solid's entry fields (8 vertices, 12 faces), with ``fields`` replacing its own."""
    raw = np.zeros((8, 3)).tobytes() + np.zeros((12, 3), dtype="<u4").tobytes() + extra
    return {"vertices": 8, "faces": 12, "data": base64.b64encode(zlib.compress(raw)).decode()} | (
        fields
    )


@pytest.mark.parametrize(
    "fields",
    [
        {"status": "passed"},
        {"distance": "nan"},
        {"location": [["0x1p+0"] * 3] * 2},
        {"surface_only": 1},
        {"closest": [["0x1p+0"] * 3, ["inf"] * 3]},
        {"solid": _solid_field(vertices=2**40)},  # claims more than MAX_SOLID_BYTES
        {"solid": _solid_field(vertices=True)},
        {"solid": _solid_field(extra=b"\0")},  # more bytes than the sizes say
        {"solid": _solid_field(faces=13)},  # fewer
        {"solid": _solid_field(vertices=0, faces=0)},
        {"solid": _solid_field(data="not base64!")},
        {"solid": {**_solid_field(), "more": 1}},
    ],
)
def test_signed_entries_out_of_domain_are_misses(tmp_path, fields):
    cache = PairCache(tmp_path, secret=b"k")
    _sign(cache, {"solid": _solid_field()})
    assert cache.get("ab" * 32).solid.faces.shape == (12, 3)  # the untouched fields are usable
    _sign(cache, fields)
    assert cache.get("ab" * 32) is None


def _sign(cache: PairCache, fields: dict) -> None:
    """Replace fields of the entry of a stored interference verdict, and sign it again."""
    cache.put("ab" * 32, _solid_verdict())
    path = cache.path("ab" * 32)
    with open(path) as f:
        entry = json.load(f)
    entry["verdict"] = {**entry["verdict"], **fields}
    entry["mac"] = cache._mac("ab" * 32, entry["verdict"])
    with open(path, "w") as f:
        json.dump(entry, f)


@pytest.mark.parametrize("mac", ["\u00e9" * 64, 7, None])
def test_a_mac_that_is_not_hex_text_is_a_miss(tmp_path, mac):
    cache = PairCache(tmp_path, secret=b"k")
    cache.put("ab" * 32, CLEAR)
    with open(cache.path("ab" * 32)) as f:
        entry = json.load(f)
    entry["mac"] = mac
    with open(cache.path("ab" * 32), "w") as f:
        json.dump(entry, f)
    assert cache.get("ab" * 32) is None


def test_a_solid_whose_faces_index_no_vertex_is_a_miss(tmp_path):
    cache = PairCache(tmp_path, secret=b"k")
    good = _solid_verdict()
    bad = PairVerdict(
        good.status, 0.0, solid=Solid(good.solid.vertices[:3], good.solid.faces), volume=1.0
    )
    cache.put("ab" * 32, bad)
    assert cache.get("ab" * 32) is None


def test_a_verdict_with_a_solid_over_the_limit_is_not_stored(tmp_path, monkeypatch):
    monkeypatch.setattr(verdicts_module, "MAX_SOLID_BYTES", 100)
    cache = PairCache(tmp_path, secret=b"k")
    cache.put("ab" * 32, _solid_verdict())
    assert not os.path.exists(cache.path("ab" * 32))


def test_oversized_entries_are_not_read(tmp_path):
    cache = PairCache(tmp_path, secret=b"k")
    cache.put("cd" * 32, CLEAR)
    assert cache.get("cd" * 32) == CLEAR
    with open(cache.path("cd" * 32), "a") as f:
        f.write(" " * (verdicts_module.MAX_PAIR_FILE_BYTES + 1))
    assert cache.get("cd" * 32) is None


def test_the_key_covers_placement_tolerance_and_clearance():
    base = dict(tolerance=1e-4, clearance=None, surfaces_apart=False)
    a, b = ("d" * 64, np.eye(4)), ("e" * 64, np.eye(4))
    key = pair_key(a, b, **base)
    moved = np.eye(4)
    moved[0, 3] = np.nextafter(0.0, 1.0)
    assert pair_key(a, ("e" * 64, moved), **base) != key
    assert pair_key(("d" * 63 + "e", np.eye(4)), b, **base) != key
    assert pair_key(a, b, **{**base, "tolerance": np.nextafter(1e-4, 1.0)}) != key
    assert pair_key(a, b, **{**base, "clearance": 0.0}) != key
    assert pair_key(a, b, **{**base, "surfaces_apart": True}) != key
    assert pair_key(b, a, **base) != key
