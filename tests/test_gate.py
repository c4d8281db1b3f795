"""The gate cannot be fooled into green: each test here is a way a CI job used to pass (exit 0)
with an interference in the assembly, or a way it used to check nothing and pass."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from meshes import box

from meshcheck.cli import main
from meshcheck.config import Approval, Groups
from meshcheck.errors import ConfigError, MeshcheckWarning
from meshcheck.load import Body
from meshcheck.pipeline import check_bodies
from meshcheck.results import Verdict


def run(args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result


def write(tmp_path, name, mesh) -> str:
    path = tmp_path / name
    mesh.export(str(path))
    return str(path)


# ------------------------------------------------------------------------------------------
# Trap 1: a far, big part must not loosen the verdict on a small pair


def frame_pin_and_rail():
    frame = box((40.0, 40.0, 10.0))
    pin = box((4.0, 4.0, 10.0), at=(0.0, 0.0, 10.0 - 0.2))  # sunk 0.2 into the frame's top face
    rail = box((20000.0, 40.0, 40.0), at=(50000.0, 0.0, 0.0))  # 20 m long, 50 m away
    return frame, pin, rail


def test_a_far_big_part_does_not_turn_an_interference_into_touching():
    frame, pin, rail = frame_pin_and_rail()
    bodies = [Body("frame", "frame", frame), Body("pin", "pin", pin), Body("rail", "rail", rail)]
    result = check_bodies(bodies, cache_dir=None)
    (finding,) = result.findings
    assert finding.status == Verdict.INTERFERENCE
    assert finding.depth == pytest.approx(0.2)
    # the tolerance that decided it comes from the frame and the pin alone
    assert finding.tolerance < 1e-3
    assert result.failed


def test_json_says_which_tolerance_decided_each_finding(tmp_path):
    frame, pin, rail = frame_pin_and_rail()
    paths = [write(tmp_path, n, m) for n, m in (("f.stl", frame), ("p.stl", pin), ("r.stl", rail))]
    out = run([*paths, "--no-cache", "--no-config", "--format", "json"])
    assert out.exit_code == 1
    doc = json.loads(out.stdout)
    (finding,) = doc["results"]
    assert finding["status"] == "interference"
    assert 0 < finding["tolerance"] < 1e-3
    assert doc["summary"]["tolerance"] is None
    assert doc["summary"]["tolerance_rule"].startswith("per pair")


# ------------------------------------------------------------------------------------------
# Trap 2: patterns that match nothing check nothing


def two_overlapping():
    a = Body("assembly/frame.stl", "assembly/frame.stl", box((1.0, 1.0, 1.0)))
    b = Body("assembly/bolt.stl", "assembly/bolt.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    return [a, b]


def test_a_group_that_matches_no_part_is_a_usage_error():
    with pytest.raises(ConfigError, match=r"groups.a \('frame.stl'\) matches no part") as info:
        check_bodies(two_overlapping(), cache_dir=None, groups=Groups(("frame.stl",), ("*",)))
    assert "assembly/bolt.stl" in str(info.value)  # shows what the names look like


def test_group_patterns_also_match_the_name_relative_to_the_argument(tmp_path):
    folder = tmp_path / "assembly"
    folder.mkdir()
    write(folder, "frame.stl", box((1.0, 1.0, 1.0)))
    write(folder, "bolt.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    (tmp_path / "meshcheck.toml").write_text('[groups]\na = ["frame.stl"]\nb = ["bolt.stl"]\n')
    out = run([folder, "--no-cache", "--config", tmp_path / "meshcheck.toml", "--format", "json"])
    assert out.exit_code == 1, out.stderr
    assert json.loads(out.stdout)["summary"]["pairs_checked"] == 1


def test_a_group_that_matches_nothing_on_the_command_line_is_exit_2(tmp_path):
    a = write(tmp_path, "a.stl", box((1.0, 1.0, 1.0)))
    b = write(tmp_path, "b.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    (tmp_path / "meshcheck.toml").write_text('[groups]\na = ["frame*"]\nb = ["*"]\n')
    out = run([a, b, "--no-cache", "--config", tmp_path / "meshcheck.toml"])
    assert out.exit_code == 2
    assert out.stdout == ""
    (line,) = out.stderr.splitlines()
    assert "matches no part" in line and "frame*" in line


def test_an_approval_that_matches_no_part_is_a_warning():
    rules = (Approval("nothing*", "*", "stale"),)
    with pytest.warns(MeshcheckWarning, match="'nothing\\*' matches no part"):
        result = check_bodies(two_overlapping(), cache_dir=None, approvals=rules)
    assert result.failed


# ------------------------------------------------------------------------------------------
# Trap 3: --fail-on never drops interference


@pytest.mark.parametrize(
    ("fail_on", "code"),
    [
        ([], 1),
        (["--fail-on", "clearance", "--clearance", "0.5"], 1),
        (["--fail-on", "touching"], 1),
        (["--fail-on", "none"], 0),
    ],
)
def test_fail_on_adds_to_interference(tmp_path, fail_on, code):
    a = write(tmp_path, "a.stl", box((1.0, 1.0, 1.0)))
    b = write(tmp_path, "b.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    assert run([a, b, "--no-cache", "--no-config", *fail_on]).exit_code == code


def test_config_fail_on_adds_to_interference(tmp_path):
    a = write(tmp_path, "a.stl", box((1.0, 1.0, 1.0)))
    b = write(tmp_path, "b.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    config = tmp_path / "meshcheck.toml"
    config.write_text('fail_on = ["touching"]\n')
    assert run([a, b, "--no-cache", "--config", config]).exit_code == 1


# ------------------------------------------------------------------------------------------
# NaN and infinity never reach the geometry


@pytest.mark.parametrize("option", ["--tolerance", "--clearance", "--threshold"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "NaN"])
def test_non_finite_options_are_usage_errors(tmp_path, option, value):
    a = write(tmp_path, "a.stl", box((1.0, 1.0, 1.0)))
    b = write(tmp_path, "b.stl", box((1.0, 1.0, 1.0), at=(0.5, 0, 0)))
    out = run([a, b, "--no-cache", "--no-config", option, value])
    assert out.exit_code == 2
    assert "finite" in out.stderr or "range" in out.stderr


@pytest.mark.parametrize("field", ["tolerance", "clearance", "threshold"])
def test_settings_refuse_non_finite_numbers(field):
    from meshcheck.settings import Settings

    with pytest.raises(ConfigError, match="finite"):
        Settings(**{field: float("nan")})


# ------------------------------------------------------------------------------------------
# A forged cache entry cannot change a verdict


def crossing_bars():
    a = box((10.0, 1.0, 1.0))
    b = box((1.0, 10.0, 1.0))
    # concave enough to be decomposed: an L of two bars each
    ell_a = trimesh.util.concatenate([a, box((1.0, 1.0, 6.0), at=(4.5, 0.0, 3.5))])
    ell_b = trimesh.util.concatenate([b, box((1.0, 1.0, 6.0), at=(0.0, 4.5, 3.5))])
    return ell_a, ell_b


FAR_PIECE = np.array(
    [[1e6, 1e6, 1e6], [1e6 + 1, 1e6, 1e6], [1e6, 1e6 + 1, 1e6], [1e6, 1e6, 1e6 + 1]]
)


@pytest.mark.parametrize("signed_with", [None, b"guessed" * 5])
def test_a_forged_cache_entry_cannot_turn_a_fail_into_a_pass(tmp_path, signed_with, monkeypatch):
    """One tiny piece a million units away, with a valid checksum (anyone can compute one),
    unsigned or signed with a key that is not the run's: checked, found not to cover, redone."""
    # A couple of parts never repay CoACD, and open ones never go (decompose.coacd_budgets):
    # force it, so there are decompositions to cache.
    monkeypatch.setenv("MESHCHECK_COACD_BUDGET", "300")
    from meshcheck.cache import DecompositionCache

    ell_a, ell_b = crossing_bars()
    a, b = write(tmp_path, "a.stl", ell_a), write(tmp_path, "b.stl", ell_b)
    cache = tmp_path / "cache"
    args = [a, b, "--cache-dir", cache, "--no-config", "-j", "1"]
    assert run(args).exit_code == 1
    store = DecompositionCache(str(cache), secret=signed_with)
    entries = sorted(cache.rglob("*.bin"))
    assert entries
    for entry in entries:
        store.put(entry.stem, [FAR_PIECE])
    assert run(args).exit_code == 1


def test_the_run_key_is_the_decomposition_cache_trust_boundary(tmp_path, monkeypatch):
    """The same forged entry signed with the run's own key is used as it is (so the test above
    would fail if signatures were not checked): whoever holds the key is trusted, as for pair
    verdicts; the key never lives in the cache directory."""
    # A couple of parts never repay CoACD, and open ones never go (decompose.coacd_budgets):
    # force it, so there are decompositions to cache.
    monkeypatch.setenv("MESHCHECK_COACD_BUDGET", "300")
    from meshcheck.cache import DecompositionCache, pair_secret

    ell_a, ell_b = crossing_bars()
    a, b = write(tmp_path, "a.stl", ell_a), write(tmp_path, "b.stl", ell_b)
    cache = tmp_path / "cache"
    args = [a, b, "--cache-dir", cache, "--no-config", "-j", "1", "--format", "json"]
    assert run(args).exit_code == 1
    store = DecompositionCache(str(cache), secret=pair_secret())
    for entry in sorted(cache.rglob("*.bin")):
        assert store.lookup(entry.stem)[1]  # the run signed what it wrote
        store.put(entry.stem, [FAR_PIECE])
    for entry in cache.rglob("pairs-v*/**/*.json"):
        entry.unlink()  # so the verdict comes from the pieces, not from the pair cache
    result = run(args)
    assert json.loads(result.stdout)["results"] == []  # the far piece was believed


def test_a_cache_entry_claiming_a_huge_array_is_a_miss(tmp_path):
    from meshcheck.cache import DecompositionCache

    store = DecompositionCache(str(tmp_path))
    key = "ab" * 32
    store.put(key, [np.eye(3)])
    path = store.path(key)
    data = bytearray(open(path, "rb").read())
    data[8:16] = (1 << 40).to_bytes(8, "little")  # the point count
    open(path, "wb").write(bytes(data))
    assert store.get(key) is None
