"""a part placed twice at the same spot is one ``duplicate`` finding per set of copies,
decided before verification, failing the run by default, in every format."""

from __future__ import annotations

import glob
import json
import os
import shutil

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.cli import main
from meshcheck.load import Body
from meshcheck.pipeline import check, check_bodies
from meshcheck.reports import FORMATS, render
from meshcheck.results import Verdict
from meshcheck.settings import Settings

SAMPLE = os.path.join(os.path.dirname(__file__), "..", "sample_meshes")


def _with_copies(tmp_path, copies: int):
    """The sample with ``copies`` extra copies of bolt_m6_a.stl, byte for byte, at its spot."""
    for path in glob.glob(os.path.join(SAMPLE, "*.stl")):
        shutil.copy(path, tmp_path)
    for k in range(copies):
        shutil.copy(tmp_path / "bolt_m6_a.stl", tmp_path / f"bolt_m6_a_copy{k}.stl")
    return sorted(str(p) for p in tmp_path.glob("*.stl"))


def test_a_doubled_part_is_one_duplicate_finding_not_an_interference(tmp_path):
    result = check(_with_copies(tmp_path, 2), config=None, cache_dir=None, jobs=1)
    duplicates = [f for f in result.findings if f.status == Verdict.DUPLICATE]
    assert len(duplicates) == 1
    (dup,) = duplicates
    assert [os.path.basename(n) for n in dup.members] == [
        "bolt_m6_a.stl",
        "bolt_m6_a_copy0.stl",
        "bolt_m6_a_copy1.stl",
    ]
    copies = set(dup.members)
    # no pair inside the set is verified or reported as an interference
    assert not any(f.a in copies and f.b in copies for f in result.findings if f is not dup)
    # each copy still meets the plate as the original does (touching)
    plate = [f for f in result.findings if f.status == Verdict.TOUCHING and "bolt_m6_a" in f.a]
    assert len(plate) == 3
    assert result.failed
    assert result.count(Verdict.DUPLICATE) == 1


def test_the_duplicate_id_is_stable_and_every_format_carries_it(tmp_path):
    paths = _with_copies(tmp_path, 1)
    first = check(paths, config=None, cache_dir=None, jobs=1)
    again = check(list(reversed(paths)), config=None, cache_dir=None, jobs=1)
    (dup,) = [f for f in first.findings if f.status == Verdict.DUPLICATE]
    assert dup.id in {f.id for f in again.findings}
    for fmt in FORMATS:
        if fmt == "html":
            continue  # draws with trimesh; the data carries the ID like every finding's
        text = render(first, fmt)
        assert dup.id in text, fmt
        assert "duplicate" in text, fmt
    doc = json.loads(render(first, "json"))
    assert doc["results"][0]["status"] == "duplicate"  # the most severe first
    assert doc["summary"]["duplicate"] == 1


def test_a_copy_moved_beyond_the_tolerance_is_not_a_duplicate():
    box = trimesh.creation.box(extents=(10, 10, 10))
    moved = np.eye(4)
    moved[0, 3] = 0.5  # 0.5 of 10: a deep interference, not a copy
    near = np.eye(4)
    near[0, 3] = 1e-6  # within the tolerance (1e-5 x 17.3)
    settings = Settings(cache_dir=None, jobs=1)
    result = check_bodies([Body("a", "a", box), Body("b", "b", box, moved)], settings)
    assert [f.status for f in result.findings] == [Verdict.INTERFERENCE]
    result = check_bodies([Body("a", "a", box), Body("b", "b", box, near)], settings)
    assert [f.status for f in result.findings] == [Verdict.DUPLICATE]


def test_two_thousand_coincident_copies_are_one_finding():
    box = trimesh.creation.box(extents=(10, 10, 10))
    bodies = [Body(f"copy{k:04d}", "x", box) for k in range(2000)]
    result = check_bodies(bodies, Settings(cache_dir=None, jobs=1))
    assert [f.status for f in result.findings] == [Verdict.DUPLICATE]
    assert len(result.findings[0].members) == 2000
    assert result.checked_pairs == []


def test_cli_fails_on_a_duplicate_and_none_lets_it_pass(tmp_path):
    paths = _with_copies(tmp_path, 1)
    runner = CliRunner()
    run = runner.invoke(main, [*paths, "--no-cache", "--no-config", "-j", "1"])
    assert run.exit_code == 1
    assert run.stdout.splitlines()[-1].startswith("FAIL: 7 parts, 1 duplicate, 1 interference")
    assert "2 copies at the same spot" in run.stdout
    passed = runner.invoke(
        main, [*paths, "--no-cache", "--no-config", "-j", "1", "--fail-on", "none"]
    )
    assert passed.exit_code == 0
    assert "Traceback" not in run.output + passed.output


@pytest.mark.parametrize("fmt", ["junit", "sarif", "github", "markdown"])
def test_a_duplicate_fails_in_the_machine_formats(tmp_path, fmt):
    result = check(_with_copies(tmp_path, 1), config=None, cache_dir=None, jobs=1)
    text = render(result, fmt)
    if fmt == "junit":
        assert 'type="duplicate"' in text
    elif fmt == "sarif":
        levels = {r["ruleId"]: r["level"] for r in json.loads(text)["runs"][0]["results"]}
        assert levels["duplicate"] == "error"
    elif fmt == "github":
        assert text.splitlines()[0].startswith("::error ") and "duplicate" in text.splitlines()[0]
    else:
        lines = text.splitlines()
        first_row = lines[next(k for k, line in enumerate(lines) if line.startswith("|---")) + 1]
        assert "| duplicate |" in first_row


@settings(derandomize=True, deadline=None, max_examples=40)
@given(
    boxes=st.lists(
        st.tuples(st.integers(0, 6), st.integers(0, 6), st.integers(1, 3)), min_size=2, max_size=12
    ),
    sets=st.lists(st.lists(st.integers(0, 11), min_size=2, max_size=4, unique=True), max_size=3),
    jitter=st.floats(0.0, 1e-3),
)
def test_the_broad_phase_of_copies_pairs_each_copy_as_itself(boxes, sets, jitter):
    # Oracle: every box against every other, the pairs inside a set left out.
    from meshcheck.geometry import pack_convex
    from meshcheck.pipeline import select_pairs

    n = len(boxes)
    taken: set[int] = set()
    copies = []
    for members in sets:  # disjoint sets of existing parts, each copy jittered off the first
        members = sorted(m for m in members if m < n and m not in taken)
        if len(members) > 1:
            taken.update(members)
            copies.append(members)
    lower = np.array([[x, y, 0.0] for x, y, _ in boxes])
    upper = lower + np.array([[s, s, 1.0] for _, _, s in boxes])
    for members in copies:
        for k, m in enumerate(members):
            lower[m], upper[m] = lower[members[0]] + k * jitter, upper[members[0]] + k * jitter
    hulls = pack_convex([np.vstack([lo, hi]) for lo, hi in zip(lower, upper, strict=True)])
    settings_ = Settings(cache_dir=None, tolerance=0.25)
    got = select_pairs(hulls, settings_, [("x",)] * n, np.ones(n), np.zeros(n), copies=copies)
    label = {m: s for s, members in enumerate(copies) for m in members}

    def near(i, j) -> bool:
        return bool(np.all(lower[j] - upper[i] <= 0.25) and np.all(lower[i] - upper[j] <= 0.25))

    expected = [
        (i, j)
        for i in range(n)
        for j in range(i + 1, n)
        if near(i, j) and not (i in label and label.get(j) == label[i])
    ]
    assert [tuple(p) for p in got.tolist()] == expected
