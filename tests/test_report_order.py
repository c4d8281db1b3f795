"""failing findings first in every format, --quiet, touching rows left out, a text
table that fits the terminal and never cuts two names to the same text."""

from __future__ import annotations

import glob
import json
import os
import re
from xml.etree import ElementTree

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.cli import main
from meshcheck.outcome import CheckResult
from meshcheck.reports import FORMATS, View, render
from meshcheck.reports.text import shorten_all
from meshcheck.results import (
    Finding,
    Location,
    PairVerdict,
    Part,
    Verdict,
    clash_groups,
    finding_id,
    group_id,
)
from meshcheck.settings import Settings, resolve_fail_on

HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=200)


def finding(a, b, status, *, depth=None, distance=0.0) -> Finding:
    verdict = PairVerdict(
        Verdict(status),
        distance,
        depth=depth,
        location=Location(np.zeros(3), np.zeros(3), np.ones(3)),
    )
    return Finding(a=a, b=b, verdict=verdict, id=finding_id(a, "1", b, "2"))


# Alphabetical order puts touching first and the shallow clash before the deep one.
FINDINGS = [
    finding("a1.stl", "a2.stl", "touching"),
    finding("b1.stl", "b2.stl", "clearance", distance=0.3),
    finding("c1.stl", "c2.stl", "clearance", distance=0.1),
    finding("d1.stl", "d2.stl", "interference", depth=0.5),
    finding("e1.stl", "e2.stl", "interference", depth=2.0),
    finding("f1.stl", "f2.stl", "touching"),
]
SEVERE_FIRST = ["e1.stl", "d1.stl", "c1.stl", "b1.stl", "a1.stl", "f1.stl"]


def make_result(findings=FINDINGS) -> CheckResult:
    names = sorted({n for f in findings for n in (f.a, f.b)})
    return CheckResult(
        findings=list(findings),
        parts=[Part(n, n, 12, True, 1) for n in names],
        settings=Settings(
            tolerance=1e-5, clearance=0.5, fail_on=resolve_fail_on(None, clearance=0.5)
        ),
    )


def _html_data(text: str) -> dict:
    found = re.search(
        r'<script type="application/json" id="meshcheck-data">(.*?)</script>', text, re.S
    )
    return json.loads(found.group(1))


def _order(fmt: str, text: str) -> list[str]:
    """The first part of each finding, in the order the report lists them."""
    if fmt in ("json",):
        return [r["a"] for r in json.loads(text)["results"]]
    if fmt == "sarif":
        return [r["properties"]["a"] for r in json.loads(text)["runs"][0]["results"]]
    if fmt == "junit":
        root = ElementTree.fromstring(text)
        return [c.get("name").split(" ")[0] for c in root.iter("testcase")]
    if fmt == "html":
        data = re.search(
            r'<script type="application/json" id="meshcheck-data">(.*?)</script>', text, re.S
        )
        return [f["a"] for f in json.loads(data.group(1))["findings"]]
    return re.findall(r"\b([a-f]1\.stl)", text.replace("\\", ""))


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_format_lists_failing_findings_first_deepest_then_closest(fmt):
    text = render(make_result(), fmt)
    order = list(dict.fromkeys(_order(fmt, text)))
    assert order[: len(SEVERE_FIRST)] == SEVERE_FIRST


@pytest.mark.parametrize("fmt", ["text", "markdown"])
def test_quiet_lists_only_failing_findings_and_the_summary(fmt):
    text = render(make_result(), fmt, view=View(is_quiet=True)).replace("\\", "")
    assert "a1.stl" not in text and "f1.stl" not in text
    for name in ("e1.stl", "d1.stl", "c1.stl", "b1.stl"):
        assert name in text
    assert "2 touching" in text  # still counted
    assert "2 findings not listed (--quiet" in text


@pytest.mark.parametrize("fmt", ["text", "markdown"])
def test_touching_rows_can_be_left_out_and_are_still_counted(fmt):
    text = render(make_result(), fmt, view=View(is_touching_listed=False)).replace("\\", "")
    assert "a1.stl" not in text and "f1.stl" not in text
    assert "e1.stl" in text
    assert "2 touching," in text
    assert "2 touching findings not listed (--hide-touching" in text


SCREWS = [
    "subassembly_gearbox/housing_left/socket_head_cap_screw.stl",
    "subassembly_gearbox/housing_right/socket_head_cap_screw.stl",
]


def test_two_screws_in_a_nested_folder_keep_different_names_in_80_columns():
    clash = finding(SCREWS[0], "frame/plate.stl", "interference", depth=1.0)
    other = finding(SCREWS[1], "frame/plate.stl", "interference", depth=0.5)
    text = render(make_result([clash, other]), "text", view=View(width=80))
    assert all(len(line) <= 80 for line in text.splitlines()), text
    rows = [line for line in text.splitlines() if line.startswith((clash.id, other.id))]
    first_names = [row.split()[2] for row in rows]
    assert len(rows) == 2 and first_names[0] != first_names[1], text
    assert "left" in first_names[0] and "right" in first_names[1]
    # today's cut: the same text for both
    assert "subassembly_gear...ad_cap_screw.stl" not in text


@HYPOTHESIS
@given(
    st.lists(st.text(alphabet="ab/._", min_size=1, max_size=60), min_size=1, max_size=8),
    st.integers(min_value=12, max_value=40),
)
def test_shortened_names_never_collide_and_fit_when_they_can(names, width):
    cut = shorten_all(names, width)
    distinct = sorted(set(names))
    assert len({cut[n] for n in distinct}) == len(distinct)
    for n in distinct:
        assert len(cut[n]) <= width or cut[n] == n


def test_the_text_table_fits_a_narrow_width_and_defaults_to_80():
    long = finding("x" * 70 + ".stl", "y" * 70 + ".stl", "interference", depth=1.0)
    assert all(
        len(line) <= 60
        for line in render(make_result([long]), "text", view=View(width=60)).splitlines()
    )
    default = render(make_result([long]), "text").splitlines()
    assert max(len(line) for line in default) == 80
    wide = render(make_result([long]), "text", view=View(width=100)).splitlines()
    assert 80 < max(len(line) for line in wide) <= 100


SAMPLE = sorted(glob.glob(os.path.join(os.path.dirname(__file__), "..", "sample_meshes", "*.stl")))


def test_cli_quiet_and_hide_touching():
    sample = SAMPLE
    runner = CliRunner()
    full = runner.invoke(main, [*sample, "--no-cache", "--no-config", "-j", "1"])
    quiet = runner.invoke(main, [*sample, "--no-cache", "--no-config", "-j", "1", "--quiet"])
    hidden = runner.invoke(
        main, [*sample, "--no-cache", "--no-config", "-j", "1", "--hide-touching"]
    )
    assert full.exit_code == quiet.exit_code == hidden.exit_code == 1
    assert "touching" in full.stdout.split("\n", 3)[-1]
    for run in (quiet, hidden):
        rows = run.stdout.splitlines()[:-1]
        assert not any(re.match(r"[0-9a-f]{12}  touching", r) for r in rows), run.stdout
        assert "4 touching findings not listed" in run.stdout or "4 findings not listed" in (
            run.stdout
        )
        assert run.stdout.splitlines()[-1] == full.stdout.splitlines()[-1]
    assert "Traceback" not in full.output + quiet.output + hidden.output


CLIPPED = [
    finding("bolt_1.stl", "bracket.stl", "interference", depth=0.2),
    finding("bolt_2.stl", "bracket.stl", "interference", depth=0.4),
    finding("bolt_3.stl", "bracket.stl", "interference", depth=0.3),
    finding("nut.stl", "shaft.stl", "interference", depth=1.0),
    finding("bolt_4.stl", "bracket.stl", "touching"),
    finding("bolt_5.stl", "bracket.stl", "touching"),
]


def test_one_bracket_clipping_many_bolts_is_one_group_in_every_human_and_json_format():
    result = make_result(CLIPPED)
    (group,) = clash_groups(result.findings)  # touching and the lone nut are not grouped
    assert (group.part, group.status) == ("bracket.stl", Verdict.INTERFERENCE)
    assert [f.a for f in group.members] == ["bolt_2.stl", "bolt_3.stl", "bolt_1.stl"]
    assert group.id == group_id("bracket.stl", "interference")  # stable: the part and status
    text = render(result, "text").splitlines()
    head = text.index(f"group {group.id}  bracket.stl: 3 interference")
    assert [line.split()[1] for line in text[head + 1 : head + 4]] == [
        "bolt_2.stl",
        "bolt_3.stl",
        "bolt_1.stl",
    ]
    doc = json.loads(render(result, "json"))
    assert doc["groups"] == [
        {
            "id": group.id,
            "kind": "part",
            "part": "bracket.stl",
            "status": "interference",
            "findings": [f.id for f in group.members],
        }
    ]
    md = render(result, "markdown")
    assert f"- `{group.id}` bracket\\.stl: 3 interference" in md
    html = render(result, "html")
    data = re.search(
        r'<script type="application/json" id="meshcheck-data">(.*?)</script>', html, re.S
    )
    assert json.loads(data.group(1))["groups"] == doc["groups"]


def test_config_quiet_and_hide_touching_and_their_command_line_opposites(tmp_path):
    config = tmp_path / "meshcheck.toml"
    config.write_text("quiet = true\nhide_touching = true\n")
    base = [*SAMPLE, "--no-cache", "-j", "1", "--config", str(config)]
    runner = CliRunner()
    quiet = runner.invoke(main, base)
    shown = runner.invoke(main, [*base, "--no-quiet", "--show-touching"])
    assert quiet.exit_code == shown.exit_code == 1
    assert "4 findings not listed (--quiet" in quiet.stdout
    assert re.search(r"[0-9a-f]{12}  touching", shown.stdout), shown.stdout
    assert "not listed" not in shown.stdout
