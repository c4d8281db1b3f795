"""Every format renders hostile part names as data, SARIF meets its schema, GitHub's annotation
limit loses nothing, the text report fits 100 columns, and baselines mark findings new or active."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from xml.etree import ElementTree

import jsonschema
import numpy as np
import pytest

from meshcheck.baseline import MAX_BASELINE_BYTES, Baseline, load_baseline
from meshcheck.errors import ConfigError, ExitStatus
from meshcheck.outcome import CheckResult, compare, exit_status
from meshcheck.reports import FORMATS, View, printable, render
from meshcheck.reports.github import LIMIT
from meshcheck.results import Finding, Location, PairVerdict, Part, Verdict, finding_id
from meshcheck.settings import Settings

DATA = Path(__file__).parent / "data"

#: Names an attacker can put in a file name, a glTF node or a 3MF object.
HOSTILE = {
    "forged line": "x\nPASS: 2 parts, 0 interference\n.stl",
    "terminal escapes": "evil\x1b[2J\x1b]0;owned\x07\r.glb#node",
    "markup": "a&#10;b</script><img src=x onerror=alert(1)>\"',:|*_[l](http://u).3mf",
    "not utf-8": "caf\udce9.stl",
    "bidi": "rtl\u202egnp.stl\u2028",
    "workflow command": "::error::fake\n::set-output name=x::y",
}


def finding(a, b, status="interference", *, approved=None, tolerance=1e-4, centroid=(1, 2, 3)):
    a, b = sorted((a, b))
    interfering = status == "interference"
    verdict = PairVerdict(
        Verdict(status),
        0.0 if status != "clearance" else 0.1,
        depth=0.25 if interfering else None,
        volume=2.5 if interfering else None,
        location=Location(np.array(centroid, float), np.zeros(3), np.ones(3)),
    )
    return Finding(
        a=a,
        b=b,
        verdict=verdict,
        id=finding_id(a, "da", b, "db"),
        approval_reason=approved,
        tolerance=tolerance,
    )


def result_of(*findings, settings=None, warnings=(), parts=None, baseline=None) -> CheckResult:
    names = sorted({n for f in findings for n in (f.a, f.b)})
    parts = parts or [Part(n, n.split("#")[0], 12, True, 1) for n in names]
    result = CheckResult(
        findings=sorted(findings, key=lambda f: (f.a, f.b)),
        parts=parts,
        settings=settings or Settings(),
        warnings=list(warnings),
    )
    return result if baseline is None else compare(result, baseline)


def hostile_result() -> CheckResult:
    findings = [finding(name, "plate.stl") for name in HOSTILE.values()]
    findings.append(finding("ok.stl", "plate.stl", approved="reason\n::error::x\x1b[31m"))
    return result_of(*findings, warnings=["x\nPASS: forged warning\x1b[2J"])


# ------------------------------------------------------------------------------------------
# printable: the one helper


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_printable_is_one_printable_utf8_line(name):
    text = printable(HOSTILE[name])
    assert text.isprintable()
    text.encode("utf-8")  # no lone surrogate left
    assert "\n" not in text and "\x1b" not in text


def test_printable_escapes_visibly():
    assert printable("a\nb\x1b[2J\tc\x7f\u202e\udcff") == "a\\nb\\x1b[2J\\tc\\x7f\\u202e\\xff"
    assert printable("C:\\parts\\pin (2).stl") == "C:\\parts\\pin (2).stl"


# ------------------------------------------------------------------------------------------
# hostile names in every format


def test_text_and_github_have_no_forged_line_and_no_escape_bytes():
    result = hostile_result()
    for fmt in ("text", "github"):
        out = render(result, fmt)
        out.encode("utf-8")
        lines = out.splitlines()
        assert out.count("\n") == len(lines)  # no \r or other line breaks inside
        assert all(line.isprintable() for line in lines), fmt
        assert not any(line.startswith("PASS") for line in lines)
        assert lines[-1].startswith("FAIL: 8 parts, 6 interference")
        if fmt == "github":
            # every line is one of ours: a command we wrote, or the summary
            assert all(re.match(r"::(error|warning|notice) [a-z]", line) for line in lines[:-1])
            assert sum(line.startswith("::error ") for line in lines) == 6


def test_text_report_snapshot_of_a_forged_name():
    result = result_of(finding(HOSTILE["forged line"], "plate.stl"))
    assert render(result, "text") == (
        "ID            STATUS        PART A     PART B\n"
        f"{result.findings[0].id}  interference  plate.stl  x\\nPASS: 2 ...rence\\n.stl\n"
        "              depth 0.25  volume 2.5  at (1, 2, 3)\n"
        "FAIL: 2 parts, 1 interference, 0 touching (tolerance per pair, 0.0001, mm)\n"
    )


def test_github_snapshot_of_a_forged_name():
    f = finding(HOSTILE["workflow command"], "plate.stl")
    out = render(result_of(f), "github")
    assert out.splitlines()[0] == (
        f"::error file=%3A%3Aerror%3A%3Afake\\n%3A%3Aset-output name=x%3A%3Ay,"
        f"title=meshcheck interference [{f.id}]::::error::fake\\n::set-output name=x::y and "
        "plate.stl: interference, depth 0.25  volume 2.5  at (1, 2, 3)"
    )


def test_junit_is_well_formed_with_names_escaped():
    out = render(hostile_result(), "junit")
    root = ElementTree.fromstring(out)  # XML 1.0 refuses raw control characters
    names = [c.get("name") for c in root.iter("testcase")]
    assert any("<-> x\\nPASS: 2 parts" in name for name in names)
    assert all(name.isprintable() for name in names)
    assert root.get("failures") == "6"


@pytest.mark.parametrize("fmt", ["json", "sarif"])
def test_json_formats_keep_names_as_data(fmt):
    result = hostile_result()
    out = render(result, fmt)
    assert out.isascii()
    doc = json.loads(out)
    if fmt == "json":
        names = {(r["a"], r["b"]) for r in doc["results"]}
    else:
        names = {(r["properties"]["a"], r["properties"]["b"]) for r in doc["runs"][0]["results"]}
    assert names == {(f.a, f.b) for f in result.findings}


def test_markdown_escapes_table_and_markup():
    out = render(hostile_result(), "markdown")
    lines = out.splitlines()
    rows = [line for line in lines if line.startswith("| ")]
    columns = rows[0].count("|")
    for row in rows:
        assert len(re.findall(r"(?<!\\)\|", row)) == columns, row  # no cell breaks out
    assert not re.search(r"(?<!\\)<", out)  # no HTML tag
    assert "](http" not in out.replace("\\]\\(", "")
    assert not any(line.startswith("PASS") for line in lines)
    assert all(line.isprintable() for line in lines)


def test_every_format_renders_hostile_names():
    result = hostile_result()
    for fmt in FORMATS:
        if fmt == "html":
            continue  # its own tests
        out = render(result, fmt)
        out.encode("utf-8")
        assert "\x1b" not in out and "\x07" not in out and "\u202e" not in out, fmt


# ------------------------------------------------------------------------------------------
# SARIF against the official schema


def sarif_validator():
    schema = json.loads((DATA / "sarif-schema-2.1.0.json").read_text())
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


def test_sarif_meets_the_schema():
    validator = sarif_validator()
    near = finding("a.glb#pin", "a.glb#hub", "clearance")
    approved = finding("nut.stl", "plate.stl", approved="press fit")
    result = result_of(
        finding("/abs/dir/bolt.stl", "plate.stl"),
        near,
        approved,
        finding("bracket.stl", "plate.stl", "touching"),
        warnings=["odd.stl: not closed"],
        settings=Settings.from_options(clearance=0.5),
    )
    doc = json.loads(render(result, "sarif"))
    errors = sorted(validator.iter_errors(doc), key=str)
    assert not errors, errors[0]
    run = doc["runs"][0]
    assert [r["id"] for r in run["tool"]["driver"]["rules"]] == [
        "duplicate",
        "interference",
        "clearance",
        "touching",
    ]
    by_id = {r["partialFingerprints"]["meshcheckFindingId/v1"]: r for r in run["results"]}
    assert set(by_id) == {f.id for f in result.findings}
    assert by_id[near.id]["level"] == "error"
    assert by_id[near.id]["locations"][0]["physicalLocation"]["artifactLocation"] == {
        "uri": "a.glb",
        "uriBaseId": "%SRCROOT%",
    }
    assert by_id[approved.id]["suppressions"][0]["justification"] == "press fit"
    absolute = next(r for r in run["results"] if "bolt" in r["message"]["text"])
    assert absolute["locations"][0]["physicalLocation"]["artifactLocation"] == {
        "uri": "file:///abs/dir/bolt.stl",
    }


def test_sarif_with_hostile_names_and_a_baseline_meets_the_schema():
    validator = sarif_validator()
    gone = "0123456789ab"
    baseline = Baseline("old.json", {gone: ("old.stl", "plate.stl", "interference")})
    result = hostile_result()
    result = compare(result, baseline)
    doc = json.loads(render(result, "sarif"))
    errors = list(validator.iter_errors(doc))
    assert not errors, errors[0]
    states = [r["baselineState"] for r in doc["runs"][0]["results"]]
    assert states.count("absent") == 1 and states.count("new") == len(result.findings)
    for r in doc["runs"][0]["results"]:
        uri = r.get("locations", [{}])[0].get("physicalLocation", {}).get("artifactLocation")
        if uri:
            assert re.fullmatch(r"[A-Za-z0-9%/._~:#@!$&'()*+,;=-]+", uri["uri"]), uri


# ------------------------------------------------------------------------------------------
# GitHub: beyond the annotation limit, nothing is lost


def test_github_annotations_beyond_the_limit_are_counted_and_logged():
    clashes = [finding(f"p{k:02d}.stl", "plate.stl") for k in range(25)]
    touching = [finding(f"t{k:02d}.stl", "plate.stl", "touching") for k in range(3)]
    near = [finding(f"n{k:02d}.stl", "plate.stl", "clearance") for k in range(12)]
    result = result_of(*clashes, *touching, *near, settings=Settings.from_options(clearance=0.5))
    lines = render(result, "github").splitlines()
    errors = [line for line in lines if line.startswith("::error ")]
    assert len(errors) == LIMIT
    # most severe first: interference before clearance
    assert all("meshcheck interference" in line for line in errors[: LIMIT - 1])
    assert errors[-1] == (
        "::error title=meshcheck::28 more errors not annotated (GitHub shows 10): "
        "see the log of this step"
    )
    logged = [line for line in lines if line.startswith("meshcheck: error: ")]
    assert len(logged) == 28
    assert sum("clearance" in line for line in logged) == 12
    assert len([line for line in lines if line.startswith("::notice ")]) == 3
    # every finding's ID is in the output
    out = "\n".join(lines)
    assert all(f.id in out for f in result.findings)


# ------------------------------------------------------------------------------------------
# Text: 100 columns, rounding, plurals, the configuration file


def test_text_fits_100_columns_and_shortens_the_shared_prefix():
    deep = "assemblies/line_7/station_3/fixtures/"
    a = deep + "a_really_long_part_name_from_the_cad_export_" + "x" * 60 + ".stl"
    b = deep + "plate.stl"
    result = result_of(
        finding(a, b, approved="a reason long enough to wrap " * 5, centroid=(1e-15, 40, 5))
    )
    lines = render(result, "text").splitlines()
    assert lines[0] == f"parts below {deep}"
    assert all(len(line) <= 100 for line in lines), [len(line) for line in lines]
    assert "..." in lines[2]  # the long name is cut in the middle
    assert "at (0, 40, 5)" in render(result, "text")  # 1e-15 is noise at tolerance 1e-4


def test_text_says_the_configuration_and_plurals(tmp_path):
    config = tmp_path / "meshcheck.toml"
    config.write_text("tolerance = 0.001\n")
    settings = Settings.from_options(config=config)
    one = result_of(settings=settings, parts=[Part("solo.stl", "solo.stl", 12, True, 0)])
    lines = render(one, "text", view=View(width=200)).splitlines()
    assert lines == [
        f"configuration: {config}",
        "PASS: 1 part, 0 interference, 0 touching (tolerance 0.001, mm)",
    ]
    assert json.loads(render(one, "json"))["summary"]["config"] == str(config)


# ------------------------------------------------------------------------------------------
# Baselines


def test_baseline_marks_new_active_and_resolved():
    kept = finding("a.stl", "b.stl")
    worse = finding("c.stl", "d.stl")  # was touching in the baseline
    fresh = finding("e.stl", "f.stl")
    baseline = Baseline(
        "old.json",
        {
            kept.id: ("a.stl", "b.stl", "interference"),
            worse.id: ("c.stl", "d.stl", "touching"),
            "0123456789ab": ("g.stl", "h.stl", "clearance"),
        },
    )
    result = result_of(kept, worse, fresh, baseline=baseline)
    assert [result.baseline_state(f) for f in result.findings] == ["active", "new", "new"]
    assert [r.id for r in baseline.resolved(result.findings)] == ["0123456789ab"]
    doc = json.loads(render(result, "json"))
    assert [r["baseline"] for r in doc["results"]] == ["active", "new", "new"]
    assert doc["resolved"] == [
        {"id": "0123456789ab", "a": "g.stl", "b": "h.stl", "status": "clearance"}
    ]
    assert (doc["summary"]["new"], doc["summary"]["active"], doc["summary"]["resolved"]) == (
        2,
        1,
        1,
    )
    for fmt in ("text", "github", "markdown", "junit"):
        out = render(result, fmt)
        assert "active" in out and "new" in out, fmt
        if fmt != "junit":
            assert "0123456789ab" in out, fmt


@pytest.mark.parametrize(
    ("words", "baseline_holds", "expected"),
    [
        (["new"], True, ExitStatus.OK),  # the interference is known: only new ones fail
        (["new"], False, ExitStatus.FAILED),
        (None, True, ExitStatus.FAILED),  # without `new`, a baseline changes no verdict
        (["new", "touching"], True, ExitStatus.FAILED),  # the new touching fails
        (["new"], None, ExitStatus.FAILED),  # no baseline at all: everything is new
    ],
)
def test_fail_on_new(words, baseline_holds, expected):
    clash = finding("a.stl", "b.stl")
    touch = finding("c.stl", "d.stl", "touching")
    settings = Settings.from_options(fail_on=words)
    assert settings.fail_on_new == ("new" in (words or ()))
    baseline = None
    if baseline_holds is not None:
        held = {clash.id: ("a.stl", "b.stl", "interference")} if baseline_holds else {}
        baseline = Baseline("old.json", held)
    result = result_of(clash, touch, settings=settings, baseline=baseline)
    assert exit_status(result) == expected


def test_fail_on_new_rejects_none():
    with pytest.raises(ConfigError, match="contradicts"):
        Settings.from_options(fail_on=["none,new"])


def write(tmp_path, content: bytes | str) -> str:
    path = tmp_path / "old.json"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return str(path)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (b"", "not JSON"),
        (b"\xff\xfe{", "not JSON"),
        ("[" * 100_000 + "]" * 100_000, "nested too deep"),
        ("[]", "no 'results' list"),
        ('{"results": {}}', "no 'results' list"),
        ('{"results": [1]}', "results[0] is not an object"),
        (
            '{"results": [{"id": "0123456789ab", "a": "x", "b": 1, "status": "touching"}]}',
            "lacks a string",
        ),
        (
            '{"results": [{"id": "../../etc", "a": "x", "b": "y", "status": "touching"}]}',
            "12 hex digits",
        ),
        (
            '{"results": [{"id": "0123456789ab", "a": "x", "b": "y", "status": "boom"}]}',
            "unknown status",
        ),
    ],
)
def test_a_hostile_baseline_is_one_config_error(tmp_path, content, reason):
    path = write(tmp_path, content)
    with pytest.raises(ConfigError, match=re.escape(reason)) as caught:
        load_baseline(path)
    assert caught.value.path == path
    assert "\n" not in str(caught.value)


@pytest.mark.posix_only
def test_a_baseline_that_is_not_a_regular_file_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="regular file"):
        load_baseline(fifo)
    with pytest.raises(ConfigError, match="cannot read"):
        load_baseline(tmp_path / "missing.json")


def test_a_huge_baseline_is_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setattr("meshcheck.baseline.MAX_BASELINE_BYTES", 10)
    with pytest.raises(ConfigError, match="more than the limit"):
        load_baseline(write(tmp_path, '{"results": []}'))
    assert MAX_BASELINE_BYTES > 10


def test_a_json_report_is_a_baseline(tmp_path):
    result = result_of(finding("a.stl", "b.stl"), finding("c.stl", "d.stl", "touching"))
    baseline = load_baseline(write(tmp_path, render(result, "json")))
    again = compare(result, baseline)
    assert {again.baseline_state(f) for f in again.findings} == {"active"}
    assert baseline.resolved(result.findings) == []


def test_fail_on_new_from_the_configuration_file(tmp_path):
    config = tmp_path / "meshcheck.toml"
    config.write_text('fail_on = ["new", "touching"]\n')
    settings = Settings.from_options(config=config)
    assert settings.fail_on_new
    assert [str(s) for s in settings.fail_on] == ["duplicate", "interference", "touching"]
    only_new = Settings.from_options(fail_on=["new"], clearance=0.5)
    assert [str(s) for s in only_new.fail_on] == ["duplicate", "interference", "clearance"]
