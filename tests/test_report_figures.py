"""What a person reads in the reports: every text line within 80 columns, one precision rule for
the figures in every format, and part names below their common folder in the HTML report too."""

from __future__ import annotations

import itertools
import json
import os
import re
import sys
from xml.etree import ElementTree

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.baseline import Baseline
from meshcheck.outcome import CheckResult, compare
from meshcheck.reports import FORMATS, View, render
from meshcheck.reports.html import render_html
from meshcheck.results import Finding, Location, PairVerdict, Part, Verdict
from meshcheck.results import finding_id as make_id
from meshcheck.settings import Settings

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), "scripts"))

DEPTH = 0.698292083  # the sample's oversized bolt, as the verify stage measures it
DEEP = "assemblies/line_7/station_3/fixtures/subassembly_gearbox_housing_left_side/"


def interference(a, b, *, tolerance, depth=DEPTH, centroid=(35.0, 15.0, 5.0)) -> Finding:
    a, b = sorted((a, b))
    verdict = PairVerdict(
        Verdict.INTERFERENCE,
        0.0,
        depth=depth,
        volume=159.512,
        location=Location(np.array(centroid), np.zeros(3), np.ones(3)),
    )
    return Finding(a, b, verdict, id=make_id(a, "da", b, "db"), tolerance=tolerance)


def touching(a, b, *, tolerance=1e-4) -> Finding:
    a, b = sorted((a, b))
    verdict = PairVerdict(
        Verdict.TOUCHING, 0.0, location=Location(np.zeros(3), np.zeros(3), np.ones(3))
    )
    return Finding(a, b, verdict, id=make_id(a, "da", b, "db"), tolerance=tolerance)


def result_of(findings, *, settings=None, config=None) -> CheckResult:
    names = sorted({n for f in findings for n in (f.a, f.b)})
    settings = settings or Settings(clearance=0.5, config_path=config)
    return CheckResult(
        sorted(findings, key=lambda f: (f.a, f.b)),
        [Part(n, n.split("#")[0], 12, True, 1) for n in names],
        settings,
    )


# ---------------------------------------------------------------------------------------------
# 80 columns


def long_result(
    *, baseline: bool = False, long_config: bool = True, with_bracket: bool = True
) -> CheckResult:
    """Copies of one clash in deep folders (a pattern group), a bracket clipping several bolts
    (a part group), approvals, a clearance setting and a configuration path of 100 characters."""
    findings = []
    for k in range(12):
        station = f"{DEEP}row_{k // 4:02d}/station_{k % 4:02d}/"
        findings.append(
            interference(station + "bolt_m8_oversized.stl", station + "plate.stl", tolerance=1e-3)
        )
        findings.append(touching(station + "bolt_m6_a.stl", station + "plate.stl"))
    bracket = DEEP + "a_really_long_bracket_name_from_the_cad_export_" + "x" * 40 + ".stl"
    for k in range(3 if with_bracket else 0):
        findings.append(interference(bracket, f"{DEEP}bolts/bolt_{k}.stl", tolerance=2e-4))
    config = "/home/someone/projects/" + "deep/" * 12 + "meshcheck.toml" if long_config else None
    result = result_of(findings, settings=Settings(clearance=0.5, config_path=config))
    if baseline:
        gone = (DEEP + "gone_" + "y" * 50 + ".stl", DEEP + "plate.stl", "interference")
        result = compare(result, Baseline(path="baseline.json", findings={"0123456789ab": gone}))
    return result


def test_every_line_of_the_text_report_fits_80_columns_by_default():
    for result in (long_result(), long_result(baseline=True)):
        for view in (View(), View(is_quiet=True), View(is_touching_listed=False)):
            text = render(result, "text", view=view)
            lines = text.splitlines()
            assert max(len(line) for line in lines) <= 80, text
            assert lines[-1].startswith("FAIL: 40 parts,"), text  # the verdict line stays last
    text = render(long_result(baseline=True), "text")
    assert "\ngroup " in text and "\nresolved 0123456789ab" in text
    # counts that do not fit the verdict line go above it, with the tolerance and the unit
    assert text.splitlines()[-2:] == [
        "1 resolved; tolerance per pair, 0.0001-0.001; lengths in mm",
        "FAIL: 40 parts, 15 interference, 12 touching, 0 clearance (< 0.5), 27 new",
    ]
    lines = render(long_result(), "text").splitlines()
    assert lines[-2] == "tolerance per pair, 0.0001-0.001; lengths in mm"


def test_a_short_summary_stays_one_line():
    result = result_of([interference("a.stl", "b.stl", tolerance=1e-4)], settings=Settings())
    assert render(result, "text").splitlines()[-1] == (
        "FAIL: 2 parts, 1 interference, 0 touching (tolerance per pair, 0.0001, mm)"
    )


def test_names_are_cut_the_same_way_in_the_table_and_the_group_lines():
    text = render(long_result(long_config=False), "text")
    bracket = next(
        line for line in text.splitlines() if line.startswith("group ") and "..." in line
    )
    name = bracket.split("  ", 1)[1].rsplit(":", 1)[0]  # the shared part, as the group names it
    rows = [line for line in text.splitlines() if re.match(r"[0-9a-f]{12}  interference", line)]
    assert any(name in row for row in rows), (name, text)


@settings(derandomize=True, deadline=None, max_examples=40)
@given(
    st.lists(
        st.text(alphabet="abcdef_/.", min_size=1, max_size=120).filter(lambda s: "//" not in s),
        min_size=2,
        max_size=6,
        unique=True,
    ),
    st.integers(min_value=40, max_value=120),
)
def test_every_text_line_fits_any_width_with_any_names(names, width):
    findings = [
        interference(DEEP + a, DEEP + b, tolerance=1e-4) for a, b in itertools.pairwise(names)
    ]
    text = render(result_of(findings), "text", view=View(width=width))
    assert max(len(line) for line in text.splitlines()) <= width, text


# ---------------------------------------------------------------------------------------------
# one precision rule


def twins() -> CheckResult:
    """Two copies of one clash whose pairs had different tolerances (the float32 floor grows with
    the distance from the origin), and a small part's shallow clash beside them."""
    return result_of(
        [
            interference("near/bolt.stl", "near/plate.stl", tolerance=4.7e-4),
            interference("far/bolt.stl", "far/plate.stl", tolerance=1.1e-3),
            interference("pin.stl", "frame.stl", tolerance=2.3e-4, depth=0.00041),
        ]
    )


def test_identical_clashes_print_the_same_figures_in_every_format():
    result = twins()
    for fmt in FORMATS:
        text = render(result, fmt)
        if fmt == "json":  # the machine format keeps every digit
            depths = [f["depth"] for f in json.loads(text)["results"]]
            assert depths.count(DEPTH) == 2
            continue
        if fmt == "html":
            data = json.loads(re.search(r'id="meshcheck-data">(.*?)</script>', text).group(1))
            shown = [f["text"]["depth"] for f in data["findings"]]
        else:
            shown = re.findall(r"depth (\d[\d.e-]*)", text)
        assert shown.count("0.6983") == 2, (fmt, shown)
        assert "0.698 " not in text
        assert "0.0004" in " ".join(shown), (fmt, shown)  # the small clash keeps its digits
    junit = ElementTree.fromstring(render(result, "junit"))
    messages = [f.get("message") for f in junit.iter("failure")]
    assert sum("depth 0.6983 " in m for m in messages) == 2


def test_the_html_labels_and_header_use_the_text_reports_figures():
    result = twins()
    page = render_html(result, [], version="0")
    data = json.loads(re.search(r'id="meshcheck-data">(.*?)</script>', page).group(1))
    assert data["settings_text"] == {"tolerance": "per pair, 0.00023-0.0011", "clearance": "0.5"}
    assert [f["text"]["volume"] for f in data["findings"]] == ["159.5"] * 3


# ---------------------------------------------------------------------------------------------
# HTML names


def test_the_html_report_data_keeps_whole_names_and_their_common_folder():
    result = long_result(long_config=False)
    page = render(result, "html")
    data = json.loads(re.search(r'id="meshcheck-data">(.*?)</script>', page).group(1))
    assert data["prefix"] == DEEP
    assert all(f["a"].startswith(DEEP) for f in data["findings"])  # matching uses whole names


@pytest.mark.browser
def test_html_names_below_their_folder_wrap_only_after_a_slash_in_a_browser(browser_page, tmp_path):
    page, errors = browser_page
    result = long_result(long_config=False, with_bracket=False)
    path = tmp_path / "report.html"
    path.write_text(render(result, "html"), encoding="utf-8")
    page.goto(path.as_uri())
    page.wait_for_function("document.body.dataset.ready")
    assert page.locator("#header p.prefix").inner_text() == f"parts below {DEEP}"
    cells = page.evaluate(
        """[...document.querySelectorAll('#findings td.part div')].map((d) => ({
            text: d.textContent,
            title: d.title,
            // each piece between two <wbr> on one line: a name breaks only after a '/'
            pieces: [...d.childNodes].filter((n) => n.nodeType === 3).map((n) => {
                const r = document.createRange(); r.selectNodeContents(n);
                return r.getClientRects().length;
            }),
            lines: (() => { const r = document.createRange(); r.selectNodeContents(d);
                const tops = new Set([...r.getClientRects()].map((b) => Math.round(b.top)));
                return tops.size; })(),
        }))"""
    )
    names = sorted(n for f in result.findings for n in (f.a, f.b))
    assert sorted(c["title"] for c in cells) == names
    assert all(c["title"] == DEEP + c["text"] for c in cells)
    assert all(set(c["pieces"]) == {1} for c in cells), cells
    assert any(c["lines"] > 1 for c in cells), cells  # the long names wrap, after a '/'
    label = page.locator("#clash-label .card div").all_text_contents()
    assert label[1:] and not any(line.startswith(DEEP) for line in label[1:])
    assert errors == []
