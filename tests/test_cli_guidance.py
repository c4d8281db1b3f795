"""a run with one part says it compared nothing (and suggests --split when the file
holds several shells); --help lists every format, STEP among the inputs, and two examples."""

from __future__ import annotations

import os

import trimesh
from click.testing import CliRunner

from meshcheck.cli import main
from meshcheck.reports import FORMATS

SAMPLE = os.path.join(os.path.dirname(__file__), "..", "sample_meshes")
OPTIONS = ["--no-cache", "--no-config", "-j", "1"]


def test_one_part_passes_with_a_warning_that_nothing_was_compared():
    run = CliRunner().invoke(main, [os.path.join(SAMPLE, "plate.stl"), *OPTIONS])
    assert run.exit_code == 0
    warning = [line for line in run.stderr.splitlines() if line.startswith("warning:")]
    assert len(warning) == 1 and "nothing to compare" in warning[0], run.stderr
    assert "--split" not in warning[0]
    assert "nothing to compare" not in run.stdout  # stdout carries the report only


def test_one_file_of_several_shells_suggests_split(tmp_path):
    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.box(extents=(1, 1, 1))
    b.apply_translation((3, 0, 0))
    path = tmp_path / "two_blocks.stl"
    trimesh.util.concatenate([a, b]).export(path)
    run = CliRunner().invoke(main, [str(path), *OPTIONS])
    assert run.exit_code == 0
    assert "it holds 2 shells: --split checks them against each other" in run.stderr
    split = CliRunner().invoke(main, [str(path), "--split", *OPTIONS])
    assert split.exit_code == 0
    assert "nothing to compare" not in split.stderr


def test_two_parts_give_no_such_warning():
    paths = [os.path.join(SAMPLE, n) for n in ("plate.stl", "bracket.stl")]
    run = CliRunner().invoke(main, [*paths, *OPTIONS])
    assert "nothing to compare" not in run.stderr


def test_help_lists_every_format_step_and_two_examples():
    text = CliRunner().invoke(main, ["--help"], terminal_width=200).stdout
    options = text[text.index("--format") : text.index("-o, --output")]
    for fmt in FORMATS:
        assert f"{fmt} (" in options or f"{fmt}," in options, fmt
    assert "STEP" in text.split("Options:")[0]
    examples = text[text.index("Examples:") : text.index("Options:")]
    assert examples.count("meshcheck ") == 2
