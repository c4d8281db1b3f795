"""Clash tests: several rules in one run, each with its own sides, clearance, failing statuses and
tolerance; verified once, judged by each; every report grouped by test."""

from __future__ import annotations

import json
import os
import sys
from xml.etree import ElementTree

import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from meshes import box_between

from meshcheck.baseline import load_baseline
from meshcheck.cli import main
from meshcheck.config import Approval, ClashTest, Groups, load_config, parse_test
from meshcheck.errors import ConfigError
from meshcheck.load import Body
from meshcheck.outcome import compare
from meshcheck.pipeline import check_bodies
from meshcheck.reports import render
from meshcheck.results import Verdict
from meshcheck.settings import Settings

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), "scripts"))

HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=12)

#: The assembly: a housing plate, an arm resting on it, a cable 0.5 above it, a bolt 2 deep in
#: it and a second bolt resting on it 1 away from the first (box corners, mm).
PARTS = {
    "housing.stl": ([0, 0, 0], [100, 100, 10]),
    "arm.stl": ([10, 10, 10], [30, 30, 40]),  # touching the housing
    "cable.stl": ([60, 10, 10.5], [70, 20, 20]),  # 0.5 above the housing
    "bolt_1.stl": ([80, 80, 8], [85, 85, 20]),  # 2 into the housing
    "bolt_2.stl": ([86, 80, 10], [91, 85, 20]),  # on the housing, 1 from bolt_1
}

#: What a CAD team writes: moving parts must clear the housing by 1 (contact fails too), the arm
#: may rest on the housing, fasteners may touch the housing but not sink into it.
CONFIG = """\
[[test]]
name = "moving parts clear the housing"
a = ["arm*", "cable*"]
b = "housing*"
clearance = 1
fail_on = ["clearance", "touching"]

[[test]]
name = "arm rests on the housing"
a = "arm*"
b = "housing*"
fail_on = ["interference"]

[[test]]
name = "fasteners"
a = "bolt_*"
b = "housing*"
"""
CLEARANCE = "moving parts clear the housing"
CONTACT = "arm rests on the housing"
FASTENERS = "fasteners"


def bodies() -> list[Body]:
    return [Body(name, name, box_between(*corners)) for name, corners in PARTS.items()]


def run_settings(**options) -> Settings:
    """Settings as the command line makes them, without a configuration file or a cache."""
    return Settings.from_options(config=None, use_cache=False, jobs=1, **options)


def config_tests(tmp_path) -> tuple[ClashTest, ...]:
    path = tmp_path / "meshcheck.toml"
    path.write_text(CONFIG)
    return load_config(path).tests


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    tests = config_tests(tmp_path_factory.mktemp("config"))
    return check_bodies(bodies(), run_settings(tests=tests))


def found(result, test: str) -> dict[tuple[str, str], str]:
    return {(f.a, f.b): str(f.status) for f in result.findings if f.test == test}


# ---------------------------------------------------------------------------------------------
# Known answers


def test_three_tests_judge_one_verification(result):
    assert [t.name for t in result.tests] == [CLEARANCE, CONTACT, FASTENERS]
    # One pair, two tests: contact fails the clearance test and passes the one that allows it.
    assert found(result, CLEARANCE) == {
        ("arm.stl", "housing.stl"): "touching",
        ("cable.stl", "housing.stl"): "clearance",
    }
    assert found(result, CONTACT) == {("arm.stl", "housing.stl"): "touching"}
    # Two groups: bolts against the housing; the bolts' 1 mm between each other is not asked.
    assert found(result, FASTENERS) == {
        ("bolt_1.stl", "housing.stl"): "interference",
        ("bolt_2.stl", "housing.stl"): "touching",
    }
    assert [result.for_test(t.name).passed for t in result.tests] == [False, True, False]
    assert result.failed_tests == [CLEARANCE, FASTENERS]
    assert result.failed
    cable = next(f for f in result.findings if f.a == "cable.stl")
    assert cable.distance == pytest.approx(0.5)


def test_settings_resolve_each_test(result):
    clearance, contact, fasteners = result.tests
    assert clearance.clearance == 1.0 and contact.clearance is None
    assert clearance.fail_on == (
        Verdict.DUPLICATE,
        Verdict.INTERFERENCE,
        Verdict.CLEARANCE,
        Verdict.TOUCHING,
    )
    assert contact.fail_on == (Verdict.DUPLICATE, Verdict.INTERFERENCE)
    assert fasteners.sides == Groups(("bolt_*",), ("housing*",))
    assert result.test_pairs[FASTENERS] == [
        ("bolt_1.stl", "housing.stl"),
        ("bolt_2.stl", "housing.stl"),
    ]


def test_finding_ids_hold_the_test(result):
    arm = [f for f in result.findings if f.a == "arm.stl"]
    assert len(arm) == 2 and arm[0].id != arm[1].id
    alone = check_bodies(bodies(), jobs=1)  # no tests: today's IDs
    plain = next(f for f in alone.findings if f.a == "arm.stl")
    assert plain.test == "" and plain.id not in {f.id for f in arm}
    assert "test" not in plain.to_dict() and arm[0].to_dict()["test"] == CLEARANCE


def test_unset_values_are_the_runs(tmp_path):
    tests = config_tests(tmp_path)
    run = run_settings(tests=tests, clearance=3, tolerance=0.01)
    clearance, contact, fasteners = run.tests
    assert (clearance.clearance, contact.clearance, fasteners.clearance) == (1.0, 3.0, 3.0)
    assert {t.tolerance for t in run.tests} == {0.01}
    assert Verdict.CLEARANCE in fasteners.fail_on  # the run's clearance fails the test
    nothing = run_settings(tests=tests, fail_on=["none"])
    assert nothing.tests[2].fail_on == () and nothing.tests[0].fail_on != ()


def test_approvals_apply_per_finding(tmp_path, result):
    arm_in_clearance = next(f for f in result.findings if f.a == "arm.stl" and f.test == CLEARANCE)
    approved = check_bodies(
        bodies(),
        run_settings(
            tests=config_tests(tmp_path),
            approvals=[Approval(None, None, "reviewed", id=arm_in_clearance.id)],
        ),
    )
    reasons = {(f.test, f.a): f.approval_reason for f in approved.findings if f.a == "arm.stl"}
    assert reasons == {(CLEARANCE, "arm.stl"): "reviewed", (CONTACT, "arm.stl"): None}


def test_baseline_states_are_per_test(tmp_path, result):
    report = tmp_path / "baseline.json"
    doc = json.loads(render(result, "json"))
    # The baseline had the clearance test only, and a finding of a test the run no longer has.
    kept = [r for r in doc["results"] if r["test"] == CLEARANCE]
    gone = {**kept[0], "id": "0123456789ab", "test": "old test"}
    report.write_text(json.dumps({"results": [*kept, gone]}))
    compared = compare(result, load_baseline(report))
    states = {(f.test, f.a): compared.baseline_state(f) for f in compared.findings}
    assert states[CLEARANCE, "arm.stl"] == "active" and states[CONTACT, "arm.stl"] == "new"
    assert [r.id for r in compared.baseline.resolved(compared.findings)] == ["0123456789ab"]
    assert compared.for_test(CLEARANCE).baseline.resolved(compared.findings) == []
    assert "resolved 0123456789ab" in render(compared, "text")  # after the sections


# ---------------------------------------------------------------------------------------------
# One verification for every test


@pytest.fixture
def verify_calls(monkeypatch):
    """Every call of the verify stage's ``verify_pair`` (run in this process: jobs=1), as the
    pairs (names of their two parts) of the pair class it decides, each pair once per call; the
    clearance of each pair's call in ``clearances``."""
    import numpy as np

    import meshcheck.pipeline as pipeline
    import meshcheck.verify.batch as batch

    real_pair, real_classes = batch.verify_pair, pipeline.verify_classes
    calls = []
    current = []  # (bodies, classes) of the verify_classes call under way

    def decided(a, b, **options):
        bodies, classes = current[-1]
        placed = [[classes.arrays(p)[0] for p in classes.placed[c]] for c in range(len(classes))]
        (c,) = [
            c
            for c, (va, vb) in enumerate(placed)
            if np.array_equal(va, a.vertices) and np.array_equal(vb, b.vertices)
        ]
        for k in classes.members()[c]:
            i, j = classes.pairs[k]
            pair = frozenset((bodies[i].name, bodies[j].name))
            calls.append(pair)
            clearances[pair] = options["clearance"]
        return real_pair(a, b, **options)

    def verify_classes(bodies, classes, *args, **kw):
        current.append((bodies, classes))
        return real_classes(bodies, classes, *args, **kw)

    monkeypatch.setattr(batch, "verify_pair", decided)
    monkeypatch.setattr(pipeline, "verify_classes", verify_classes)

    def run(parts, settings):
        calls.clear()
        clearances.clear()
        out = check_bodies(parts, settings)
        return out, list(calls)

    clearances: dict = {}
    run.clearances = clearances
    return run


def test_verify_runs_once_per_pair_whatever_the_number_of_tests(tmp_path, verify_calls):
    parts = bodies()
    tests = config_tests(tmp_path)
    three, calls_three = verify_calls(parts, run_settings(tests=tests))
    # the pairs the tests hold within their reach, each verified once
    assert sorted(calls_three, key=sorted) == [
        frozenset(p)
        for p in [
            ("arm.stl", "housing.stl"),
            ("bolt_1.stl", "housing.stl"),
            ("bolt_2.stl", "housing.stl"),
            ("cable.stl", "housing.stl"),
        ]
    ]
    # each pair with the largest clearance of the tests that hold it, none for the fasteners'
    assert {min(p): c for p, c in verify_calls.clearances.items()} == {
        "arm.stl": 1.0,
        "cable.stl": 1.0,
        "bolt_1.stl": None,
        "bolt_2.stl": None,
    }
    twice = tests + tuple(
        ClashTest(f"copy {k}", t.sides, t.clearance, t.fail_on) for k, t in enumerate(tests)
    )
    six, calls_six = verify_calls(parts, run_settings(tests=twice))
    assert sorted(calls_six, key=sorted) == sorted(calls_three, key=sorted)
    assert len(six.findings) == 2 * len(three.findings)
    # one test of every part at the largest clearance: the same pairs and the bolts' one more
    _, calls_one = verify_calls(parts, run_settings(tests=["all:*:*:clearance=1"]))
    assert len(calls_one) == len(set(calls_one)) == 5
    assert set(calls_three) < set(calls_one)


def test_a_second_tolerance_verifies_its_pairs_again(verify_calls):
    parts = bodies()
    tests = [parse_test("fine:bolt_*:housing*"), parse_test("coarse:bolt_*:*:tolerance=1.5")]
    result, calls = verify_calls(parts, run_settings(tests=tests))
    pair_sets = {frozenset(("bolt_1.stl", "housing.stl")), frozenset(("bolt_2.stl", "housing.stl"))}
    # the bolts against the housing are held by both tolerances: verified at each, counted
    assert sorted(calls, key=sorted).count(frozenset(("bolt_1.stl", "housing.stl"))) == 2
    assert len(calls) == len(pair_sets) * 2 + 1  # and bolt_1 x bolt_2 at the coarse one
    assert found(result, "fine")[("bolt_1.stl", "housing.stl")] == "interference"
    # at 1.5 the bolts 1 apart touch; at the default they do not
    assert found(result, "coarse")[("bolt_1.stl", "bolt_2.stl")] == "touching"


# ---------------------------------------------------------------------------------------------
# Each test sees what a run of that test alone sees


SIDES = st.sampled_from(["*", "housing*", "bolt_*", "arm*", "cable*", "bolt_1*"])


@st.composite
def clash_tests(draw):
    count = draw(st.integers(1, 3))
    out = []
    for k in range(count):
        out.append(
            ClashTest(
                f"t{k}",
                Groups((draw(SIDES),), (draw(SIDES),)),
                draw(st.sampled_from([None, 0.3, 0.7, 1.2, 5.0])),
                draw(st.sampled_from([None, ("touching",), ("none",)])),
                draw(st.sampled_from([None, None, 0.01])),
            )
        )
    return out


@HYPOTHESIS
@given(tests=clash_tests())
def test_each_test_sees_what_a_run_of_it_alone_sees(tests):
    parts = bodies()
    run = run_settings(tests=tests)
    together = check_bodies(parts, run)
    for test in run.tests:
        alone = check_bodies(
            parts,
            Settings(
                groups=test.sides,
                clearance=test.clearance,
                tolerance=test.tolerance,
                fail_on=test.fail_on,
                jobs=1,
            ),
        )
        mine = together.for_test(test.name)

        def seen(r):
            return [(f.a, f.b, f.status, f.distance, f.depth, f.volume) for f in r.findings]

        assert seen(mine) == seen(alone)
        assert mine.passed == alone.passed
    assert together.passed == all(together.for_test(t.name).passed for t in run.tests)


# ---------------------------------------------------------------------------------------------
# Every format shows the tests


def test_every_format_groups_findings_by_test(result):
    text = render(result, "text")
    heads = [line for line in text.splitlines() if line.startswith("test ")]
    assert [h.split(":")[0] for h in heads] == [f"test {t.name}" for t in result.tests]
    assert text.splitlines()[-1].startswith("FAIL: 5 parts, 3 tests, 2 failing")

    doc = json.loads(render(result, "json"))
    assert [t["name"] for t in doc["tests"]] == [CLEARANCE, CONTACT, FASTENERS]
    assert [t["passed"] for t in doc["tests"]] == [False, True, False]
    ids = {r["id"]: r["test"] for r in doc["results"]}
    for entry in doc["tests"]:
        assert {ids[i] for i in entry["findings"]} <= {entry["name"]}
        # every finding of the test listed, none missing (an empty list would pass the line above)
        assert sorted(entry["findings"]) == sorted(i for i, t in ids.items() if t == entry["name"])
        assert entry["summary"]["passed"] == entry["passed"]
    assert doc["summary"]["failed_tests"] == [CLEARANCE, FASTENERS]

    root = ElementTree.fromstring(render(result, "junit"))
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == [CLEARANCE, CONTACT, FASTENERS]
    assert [s.get("failures") for s in suites] == ["2", "0", "1"]
    assert root.get("failures") == "3"

    sarif = json.loads(render(result, "sarif"))["runs"][0]
    rules = [r["id"] for r in sarif["tool"]["driver"]["rules"]]
    for entry in sarif["results"]:
        test, status = entry["ruleId"].split("/")
        assert test == entry["properties"]["test"] and status in entry["message"]["text"]
        assert rules[entry["ruleIndex"]] == entry["ruleId"]

    github = render(result, "github").splitlines()
    assert any(f"title=meshcheck {FASTENERS}%3A interference" in line for line in github)
    assert sum(line.startswith("meshcheck: test ") for line in github) == 3

    markdown = render(result, "markdown")
    assert [line for line in markdown.splitlines() if line.startswith("### ")] == [
        f"### ❌ {CLEARANCE}: FAIL",
        f"### ✅ {CONTACT}: PASS",
        f"### ❌ {FASTENERS}: FAIL",
    ]

    data = json.loads(render(result, "html").split('id="meshcheck-data">')[1].split("</script>")[0])
    assert [t["name"] for t in data["tests"]] == [CLEARANCE, CONTACT, FASTENERS]
    assert {f["test"] for f in data["findings"]} == {CLEARANCE, CONTACT, FASTENERS}


def test_a_run_without_tests_names_none(result):
    alone = check_bodies(bodies(), jobs=1)
    doc = json.loads(render(alone, "json"))
    assert "tests" not in doc and all("test" not in r for r in doc["results"])
    assert "tests.js" not in render(alone, "html") and "test-filter" not in render(alone, "html")


@pytest.mark.browser
def test_html_filter_by_test(result, browser_page, tmp_path):
    page, errors = browser_page
    path = tmp_path / "tests.html"
    path.write_text(render(result, "html"), encoding="utf-8")
    page.goto(path.as_uri())
    page.wait_for_function("document.body.dataset.tests === 'ready'")
    assert page.locator("#tests li").count() == 3
    assert page.locator("#tests li .verdict").all_inner_texts() == ["FAIL", "PASS", "FAIL"]
    rows = page.locator("#findings tbody tr:visible")
    assert rows.count() == len(result.findings) == 5
    page.select_option("#test-filter", FASTENERS)
    assert rows.count() == 2
    assert {rows.nth(k).get_attribute("data-test") for k in range(2)} == {FASTENERS}
    drawn = "window.meshcheckView.scene.children.filter(o => o.renderOrder === 3)"
    shown = page.evaluate(f"{drawn}.filter(o => o.visible).length")
    assert shown == 1  # the bolt's shared solid; the other tests' markers are hidden
    page.locator("#filters input[data-status=touching]").uncheck()
    assert rows.count() == 1  # both filters apply
    page.select_option("#test-filter", "")
    page.locator("#filters input[data-status=touching]").check()
    assert rows.count() == 5
    assert errors == []


# ---------------------------------------------------------------------------------------------
# Configuration and the command line


def invoke(args, **kwargs):
    out = CliRunner().invoke(main, [str(a) for a in args], **kwargs)
    assert "Traceback" not in out.stderr
    assert out.exception is None or isinstance(out.exception, SystemExit), out.exception
    return out


@pytest.fixture(scope="module")
def stl_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("parts")
    for body in bodies():
        body.mesh.export(folder / body.name)
    return folder, [str(folder / name) for name in PARTS]


def test_command_line_runs_the_configuration_tests(stl_files):
    folder, files = stl_files
    (folder / "meshcheck.toml").write_text(CONFIG)
    out = invoke([*files, "--config", folder / "meshcheck.toml", "--no-cache", "-j", "1"])
    assert out.exit_code == 1
    assert out.stdout.splitlines()[-1].startswith("FAIL: 5 parts, 3 tests, 2 failing")
    quiet = invoke([*files, "--no-cache", "--no-config", "-j", "1", "--test", f"{CONTACT}:arm*:*"])
    assert quiet.exit_code == 0, quiet.stdout  # the arm rests on the housing: touching only
    assert quiet.stdout.splitlines()[0].startswith(f"test {CONTACT}: arm* against all parts")


def test_test_option_replaces_the_files_tests(stl_files):
    folder, files = stl_files
    (folder / "meshcheck.toml").write_text(CONFIG)
    config = ["--config", folder / "meshcheck.toml", "--no-cache", "-j", "1", "--format", "json"]
    out = invoke([*files, *config, "--test", "bolts:bolt_1*:bolt_2*:clearance=2:fail_on=none"])
    assert out.exit_code == 0, out.stderr
    doc = json.loads(out.stdout)
    assert [t["name"] for t in doc["tests"]] == ["bolts"]
    assert [(r["status"], r["distance"]) for r in doc["results"]] == [("clearance", 1.0)]


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("bolts", "'bolts' is not NAME:A:B"),
        ("bolts:bolt_*:housing*:clearance=-1", "clearance = -1 is out of range"),
        ("bolts:bolt_*:housing*:depth=1", "'depth=1' is not KEY=VALUE"),
        ("bolts:bolt_*:housing*:fail_on=new", "fail_on 'new' is for the whole run"),
        ("bolts:bolt_*:housing*:fail_on=sometimes", "unknown fail-on status 'sometimes'"),
        ("bolts:nut_*:housing*", "test 'bolts': a ('nut_*') matches no part"),
        ("bolts::housing*", "a must be a glob pattern"),
        ("bo\x1bts:*:*", "must be printable"),
    ],
)
def test_bad_test_options_are_one_line(stl_files, option, message):
    _, files = stl_files
    out = invoke([*files, "--no-cache", "--no-config", "-j", "1", "--test", option])
    assert out.exit_code == 2
    lines = out.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ") and message in lines[-1], out.stderr
    assert out.stdout == ""


def test_two_tests_of_one_name_are_refused(stl_files):
    _, files = stl_files
    out = invoke([*files, "--no-cache", "--no-config", "--test", "x:*:*", "--test", "x:a*:b*"])
    assert out.exit_code == 2
    assert out.stderr.strip() == (
        "error: two clash tests are named 'x': each test needs its own name"
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[[test]]\na = "x"\n', "test entry 1 has no 'name'"),
        ('[[test]]\nname = "x"\n[[test]]\nname = "x"\n', "two clash tests are named 'x'"),
        ('[[test]]\nname = "x"\nside = "y"\n', "test 'x': unknown key 'side'"),
        ('[[test]]\nname = "x"\na = []\n', "test 'x': a must be a glob pattern"),
        ('[[test]]\nname = "x"\nclearance = "1"\n', "test 'x': clearance must be a number"),
        ('[[test]]\nname = "x"\ntolerance = -0.1\n', "test 'x': tolerance = -0.1 is out of"),
        ('[[test]]\nname = "x"\nfail_on = ["new"]\n', "fail_on 'new' is for the whole run"),
        ('[[test]]\nname = "x"\nfail_on = [1]\n', "fail_on must be a list of strings"),
        ('[[test]]\nname = ""\n', "a clash test needs a name"),
        ('[[test]]\nname = "a:b"\n', "without ':'"),
        ('test = {name = "x"}\n', "test must be an array of tables"),
        ("test = [1]\n", "test entry 1 must be a table"),
    ],
)
def test_bad_test_tables_are_refused(tmp_path, text, message):
    path = tmp_path / "meshcheck.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as raised:
        load_config(path)
    assert str(raised.value).startswith(f"{path}: ") and message in str(raised.value)


def test_test_tables_in_pyproject(tmp_path):
    path = tmp_path / "pyproject.toml"
    path.write_text(
        '[tool.meshcheck]\nclearance = 2\n\n[[tool.meshcheck.test]]\nname = "all"\n\n'
        '[[tool.meshcheck.test]]\nname = "bolts"\na = ["bolt_*"]\nb = ["bolt_*"]\n'
        'clearance = 0.5\nfail_on = "touching"\ntolerance = 0.01\n'
    )
    config = load_config(path)
    assert config.tests == (
        ClashTest("all"),
        ClashTest("bolts", Groups(("bolt_*",), ("bolt_*",)), 0.5, ("touching",), 0.01),
    )
    run = Settings.from_options(config=config)
    assert [t.clearance for t in run.tests] == [2.0, 0.5]


def test_groups_and_tests_are_refused_together(tmp_path):
    path = tmp_path / "meshcheck.toml"
    path.write_text('[groups]\na = "x"\nb = "y"\n\n[[test]]\nname = "t"\n')
    with pytest.raises(ConfigError, match="groups and clash tests cannot be combined"):
        Settings.from_options(config=path)
