"""The decomposition cache: bit-exact round trips, corrupt entries are misses, concurrency."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from meshcheck.cache import DecompositionCache, decomposition_key
from meshcheck.cache import decompositions as decompositions_module
from meshcheck.cache.store import checksum

KEY = "0f" * 32
PIECES = [np.arange(12.0).reshape(4, 3) / 7.0, np.array([[1e5, -1e-300, np.pi]])]


def same(a, b) -> bool:
    return len(a) == len(b) and all(
        x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
        for x, y in zip(a, b, strict=True)
    )


def test_round_trip_is_bit_exact(tmp_path):
    cache = DecompositionCache(str(tmp_path))
    assert cache.get(KEY) is None
    cache.put(KEY, PIECES)
    assert same(cache.get(KEY), PIECES)
    assert cache.get("1" * 64) is None


@settings(derandomize=True, deadline=None, max_examples=30)
@given(
    st.lists(
        hnp.arrays(
            np.float64,
            st.tuples(st.integers(1, 6), st.just(3)),
            elements=st.floats(allow_nan=False, allow_infinity=False, width=64),
        ),
        min_size=0,
        max_size=4,
    )
)
def test_round_trip_property(tmp_path_factory, pieces):
    cache = DecompositionCache(str(tmp_path_factory.mktemp("c")))
    cache.put(KEY, pieces)
    assert same(cache.get(KEY), pieces)


def test_key_covers_digest_options_versions(monkeypatch):
    base = decomposition_key("a" * 64, {"threshold": 0.1})
    assert base == decomposition_key("a" * 64, {"threshold": 0.1})
    assert base != decomposition_key("b" * 64, {"threshold": 0.1})
    assert base != decomposition_key("a" * 64, {"threshold": 0.2})
    monkeypatch.setattr(decompositions_module, "package_version", lambda name: "0.0.1")
    assert base != decomposition_key("a" * 64, {"threshold": 0.1})
    monkeypatch.undo()
    version = decompositions_module.FORMAT_VERSION
    monkeypatch.setattr(decompositions_module, "FORMAT_VERSION", version + 1)
    assert base != decomposition_key("a" * 64, {"threshold": 0.1})


def _truncate(path):
    data = open(path, "rb").read()
    open(path, "wb").write(data[: len(data) // 2])


def _garbage(path):
    open(path, "wb").write(b"\x00garbage" * 100)


def _empty(path):
    open(path, "wb").close()


def _rewrite(path, edit):
    """Apply ``edit`` to the entry's header fields and body, and write it back."""
    header = DecompositionCache.HEADER
    data = open(path, "rb").read()
    fields = list(header.unpack(data[: header.size]))
    body = bytearray(data[header.size :])
    edit(fields, body)
    open(path, "wb").write(header.pack(*fields) + bytes(body))


def _more_points_than_held(path):
    def edit(fields, body):
        fields[1] = 1 << 40  # a (2^40, 3) claim: a miss before any allocation

    _rewrite(path, edit)


def _bad_starts(path):
    def edit(fields, body):
        body[8:16] = (9).to_bytes(8, "little")

    _rewrite(path, edit)


def _flipped_value(path):
    def edit(fields, body):
        body[-1] ^= 1

    _rewrite(path, edit)


def _wrong_magic(path):
    def edit(fields, body):
        fields[0] = b"NOTMINE!"

    _rewrite(path, edit)


def _extra_bytes(path):
    def edit(fields, body):
        body.extend(b"\0" * 24)

    _rewrite(path, edit)


def _nan_point_with_matching_checksum(path):
    """A forged entry with a valid checksum (anyone can compute one) and a NaN coordinate."""
    header = DecompositionCache.HEADER
    data = open(path, "rb").read()
    fields = list(header.unpack(data[: header.size]))
    body = bytearray(data[header.size :])
    body[-8:] = np.float64(np.nan).tobytes()
    fields[3] = checksum(KEY.encode(), bytes(body))
    open(path, "wb").write(header.pack(*fields) + bytes(body))


@pytest.mark.parametrize(
    "damage",
    [
        _truncate,
        _garbage,
        _empty,
        _more_points_than_held,
        _bad_starts,
        _flipped_value,
        _wrong_magic,
        _extra_bytes,
        _nan_point_with_matching_checksum,
    ],
)
def test_corrupt_entry_is_a_miss_and_is_rewritten(tmp_path, damage):
    cache = DecompositionCache(str(tmp_path))
    cache.put(KEY, PIECES)
    damage(cache.path(KEY))
    assert cache.get(KEY) is None
    cache.put(KEY, PIECES)
    assert same(cache.get(KEY), PIECES)


def test_entry_under_another_key_is_rejected(tmp_path):
    cache = DecompositionCache(str(tmp_path))
    cache.put(KEY, PIECES)
    other = "ab" * 32
    os.makedirs(os.path.dirname(cache.path(other)), exist_ok=True)
    os.replace(cache.path(KEY), cache.path(other))
    assert cache.get(other) is None


def test_unwritable_directory_only_costs_a_miss(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    cache = DecompositionCache(str(blocker))
    cache.put(KEY, PIECES)  # no exception
    assert cache.get(KEY) is None


def test_stale_temporary_files_are_removed(tmp_path):
    cache = DecompositionCache(str(tmp_path))
    cache.put(KEY, PIECES)
    folder = os.path.dirname(cache.path(KEY))
    stale, fresh = os.path.join(folder, ".tmp-old.npz"), os.path.join(folder, ".tmp-new.npz")
    for path in (stale, fresh):
        open(path, "wb").write(b"partial")
    os.utime(stale, (0, 0))
    cache.put(KEY, PIECES)
    assert not os.path.exists(stale) and os.path.exists(fresh)


def _writer(directory: str, barrier, seconds: float) -> None:
    import time

    cache = DecompositionCache(directory)
    barrier.wait(30)  # both processes start writing at the same moment
    stop = time.monotonic() + seconds
    rounds = 0
    while time.monotonic() < stop or rounds < 20:
        cache.put(KEY, PIECES)
        got = cache.get(KEY)
        assert got is not None and same(got, PIECES)
        rounds += 1


def test_two_processes_writing_one_key_both_succeed(tmp_path):
    context = multiprocessing.get_context("spawn")
    barrier = context.Barrier(2)
    procs = [context.Process(target=_writer, args=(str(tmp_path), barrier, 0.5)) for _ in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0]
    cache = DecompositionCache(str(tmp_path))
    assert same(cache.get(KEY), PIECES)
    leftovers = [n for n in os.listdir(os.path.dirname(cache.path(KEY))) if n.startswith(".tmp")]
    assert leftovers == []


def test_warm_run_gives_byte_identical_json(tmp_path, monkeypatch):
    """Cold run, warm run and a run without cache agree byte for byte."""
    # A couple of parts never repay CoACD, and open ones never go (decompose.coacd_budgets):
    # force it, so there are decompositions to cache.
    monkeypatch.setenv("MESHCHECK_COACD_BUDGET", "300")
    from meshcheck.pipeline import check
    from meshcheck.reports import render

    samples = os.path.join(os.path.dirname(__file__), "..", "sample_meshes")
    paths = [os.path.join(samples, f"{n}.stl") for n in ("plate", "bolt_m8_oversized", "bracket")]
    cold = render(check(paths, cache_dir=str(tmp_path), jobs=1), "json")
    assert list(tmp_path.rglob("*.bin"))
    warm = render(check(paths, cache_dir=str(tmp_path), jobs=1), "json")
    uncached = render(check(paths, cache_dir=None, jobs=2), "json")
    assert cold == warm == uncached
    assert '"interference"' in cold


def test_warm_run_does_not_import_coacd(tmp_path):
    """A warm run pays for no CoACD import (nor does a cold one: CoACD runs in workers)."""
    import subprocess
    import sys

    samples = os.path.join(os.path.dirname(__file__), "..", "sample_meshes")
    paths = [os.path.join(samples, f"{n}.stl") for n in ("plate", "bolt_m8_oversized")]
    script = (
        "import sys\n"
        "from meshcheck.pipeline import check\n"
        f"check({paths!r}, cache_dir={str(tmp_path)!r})\n"
        "print('coacd' in sys.modules)\n"
    )
    root = os.path.join(os.path.dirname(__file__), "..")
    for _ in ("cold", "warm"):
        out = subprocess.run(
            [sys.executable, "-c", script], capture_output=True, text=True, cwd=root, check=True
        )
        assert out.stdout.strip() == "False"
