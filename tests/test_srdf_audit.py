"""The SRDF audit: each pair an SRDF disables proven never over the joint ranges, or shown
colliding at a witness pose an independent check confirms; only those pairs swept; every format
lists the wrong ones; the corrected SRDF; the SRDF read as the hostile input it may be.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from robot_oracle import collide, link_poses, posed, read_robot
from test_html_report import open_report  # and scripts/, where the browser fixture's driver is
from test_report_formats import sarif_validator
from test_sweep import STOP_ANGLE, door

from meshcheck.cli import main
from meshcheck.errors import ExitStatus, InputError
from meshcheck.load.srdf import MAX_SRDF_ELEMENTS, parse_srdf, read_srdf
from meshcheck.pipeline import check
from meshcheck.reports import render
from meshcheck.reports.srdf import corrected

ROBOTS = os.path.join(os.path.dirname(__file__), "data", "robots")
PANDA = os.path.join(ROBOTS, "panda_description", "urdf", "panda.urdf")
PANDA_SRDF = os.path.join(ROBOTS, "panda_moveit_config", "config", "panda.srdf")
PANDA_PACKAGE = {"moveit_resources_panda_description": os.path.join(ROBOTS, "panda_description")}


def srdf(*entries: tuple[str, str, str], name: str = "door") -> str:
    lines = "".join(
        f'  <disable_collisions link1="{a}" link2="{b}" reason="{reason}"/>\n'
        for a, b, reason in entries
    )
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{lines}</robot>\n'


def write(folder, name: str, text: str) -> str:
    path = folder / name
    path.write_text(text)
    return str(path)


def run_cli(*args):
    result = CliRunner().invoke(main, [*map(str, args), "--no-cache", "--no-config", "-j", "1"])
    assert "Traceback" not in (result.stderr or "")
    return result


def audited(*args) -> tuple[int, dict]:
    run = run_cli(*args, "--format", "json")
    return run.exit_code, json.loads(run.stdout)


# ------------------------------------------------------------------------------------------
# Known answers: a door and its stop (tests/test_sweep.py's, closed form STOP_ANGLE)


def test_a_never_entry_past_the_stop_fails_with_a_witness_the_oracle_confirms(tmp_path):
    upper = STOP_ANGLE + 0.05
    urdf = write(tmp_path, "door.urdf", door(upper))
    entries = srdf(("door", "stop", "Never"))
    status, doc = audited(urdf, "--audit-srdf", write(tmp_path, "door.srdf", entries))
    assert status == ExitStatus.FAILED
    (pair,) = doc["audit"]["pairs"]
    assert (pair["a"], pair["b"], pair["reason"], pair["line"]) == ("door", "stop", "Never", 3)
    assert pair["status"] == "sometimes" and pair["wrong"] and pair["failed"]
    assert STOP_ANGLE - 1e-6 <= pair["pose"]["hinge"] <= upper
    assert doc["summary"]["wrongly_disabled"] == 1 and not doc["summary"]["passed"]
    assert "sweeps" not in doc  # an audit sweeps the SRDF's pairs, and reports them apart
    oracle = read_robot(urdf)
    assert collide(oracle, "door", "stop", pair["pose"]) == "contact"


def test_a_never_entry_short_of_the_stop_is_proven(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE - 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    status, doc = audited(urdf, "--audit-srdf", path)
    assert status == ExitStatus.OK
    (pair,) = doc["audit"]["pairs"]
    assert pair["status"] == "never" and not pair["wrong"] and pair["pose"] is None
    assert doc["summary"]["wrongly_disabled"] == 0


def first_contact(stop: tuple[float, float], step: float = 2e-4) -> float:
    """The smallest hinge angle at which python-fcl sees the door (tests/test_sweep.py's)
    touch a stop box whose lower left corner is ``stop``: a scan of the one joint."""
    robot = read_robot_text(door(math.pi, stop_at=_centre(stop)))
    for angle in np.arange(0.0, math.pi / 2, step):
        if collide(robot, "door", "stop", {"hinge": float(angle)}, tolerance=0.0):
            return float(angle)
    return math.inf


def _centre(corner: tuple[float, float]) -> str:
    return f"{corner[0] + 0.15!r} {corner[1] + 0.1!r} 0"


def read_robot_text(text: str):
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "door.urdf")
        with open(path, "w") as fh:
            fh.write(text)
        return read_robot(path)


@settings(max_examples=8, derandomize=True, deadline=None)
@given(
    x=st.floats(0.2, 0.6),
    y=st.floats(0.12, 0.5),
    beyond=st.sampled_from([-0.02, 0.02]),
)
def test_the_audit_agrees_with_a_scan_of_the_hinge(tmp_path_factory, x, y, beyond):
    """A stop box anywhere in reach: the Never entry is wrong exactly when the hinge's limit
    passes the first contact a python-fcl scan of the hinge finds (0.02 rad either side of it),
    and the witness lies between that angle and the limit."""
    contact = first_contact((x, y))
    upper = contact + beyond
    folder = tmp_path_factory.mktemp("door")
    urdf = write(folder, "door.urdf", door(upper, stop_at=_centre((x, y))))
    path = write(folder, "d.srdf", srdf(("door", "stop", "Never")))
    status, doc = audited(urdf, "--audit-srdf", path)
    (pair,) = doc["audit"]["pairs"]
    if beyond < 0:
        assert status == ExitStatus.OK and pair["status"] == "never"
    else:
        assert status == ExitStatus.FAILED and pair["status"] == "sometimes"
        assert contact - 2e-4 - 1e-5 <= pair["pose"]["hinge"] <= upper


# ------------------------------------------------------------------------------------------
# What is swept, which entries are audited


def chain(links: int = 4) -> str:
    """Boxes 0.2 wide, 1 m apart along x, each on a revolute joint about z at its parent."""
    body = "".join(
        f'<link name="l{k}"><collision><geometry><box size="0.2 0.2 0.2"/></geometry>'
        "</collision></link>"
        for k in range(links)
    )
    body += '<link name="bare"/><joint name="fb" type="fixed"><parent link="l0"/>'
    body += '<child link="bare"/></joint>'
    for k in range(1, links):
        body += (
            f'<joint name="j{k}" type="revolute"><origin xyz="1 0 0"/><parent link="l{k - 1}"/>'
            f'<child link="l{k}"/><axis xyz="0 0 1"/><limit lower="-0.5" upper="0.5"/></joint>'
        )
    return f'<robot name="chain">{body}</robot>'


def test_only_the_pairs_the_srdf_names_are_swept(tmp_path):
    from meshcheck.load import load_assembly
    from meshcheck.settings import Settings
    from meshcheck.sweep import mechanism_pieces

    urdf = write(tmp_path, "chain.urdf", chain())
    path = write(tmp_path, "c.srdf", srdf(("l0", "l2", "Never"), ("l1", "l2", "Adjacent")))
    settings = Settings.from_options(config=None, cache_dir=None, motion={"audit": path})
    assembly = load_assembly([urdf], motion=settings.motion)
    pieces = mechanism_pieces(assembly.bodies, assembly.mechanisms, settings)
    names = sorted(assembly.bodies[k].name.rpartition("#")[2] for k in pieces)
    assert names == ["l0", "l2"]  # the Adjacent entry is not audited: l1 is not decomposed
    result = check([urdf], settings)
    assert [(p.a, p.b, p.status) for p in result.audit.pairs] == [("l0", "l2", "never")]
    assert result.audit.unaudited == 1 and result.sweeps == ()


@pytest.mark.parametrize(
    ("reasons", "expected"),
    [
        (None, [("l0", "l2")]),
        ("Adjacent", [("l1", "l2")]),
        ("never,ADJACENT", [("l0", "l2"), ("l1", "l2")]),
        ("all", [("l0", "l2"), ("l1", "l2"), ("bare", "l3")]),
    ],
)
def test_the_reasons_audited(tmp_path, reasons, expected):
    urdf = write(tmp_path, "chain.urdf", chain())
    entries = (("l2", "l0", "Never"), ("l1", "l2", "Adjacent"), ("l3", "bare", "User"))
    path = write(tmp_path, "c.srdf", srdf(*entries))
    args = [urdf, "--audit-srdf", path] + ([] if reasons is None else ["--audit-reasons", reasons])
    _, doc = audited(*args)
    assert [(p["a"], p["b"]) for p in doc["audit"]["pairs"]] == expected
    assert doc["audit"]["unaudited"] == 3 - len(expected)
    bare = [p for p in doc["audit"]["pairs"] if "bare" in (p["a"], p["b"])]
    assert all(p["status"] == "never" for p in bare)  # no collision geometry: nothing collides


@pytest.mark.parametrize("sweep", [[], ["--sweep"]])
def test_an_audited_pair_the_budget_does_not_reach_is_undecided_never_never(tmp_path, sweep):
    """With the whole default budget every audited pair of the chain is proven never; with a
    budget of 1 only the first pair visited is swept, and it finishes the batch of boxes it is
    in (the audit's first, l0 / l2, is proven in its first; the sweep's first is l0 / l1): the
    pairs not reached are undecided (kept, not failing), the pair without geometry still never,
    and the summary says the budget."""
    urdf = write(tmp_path, "chain.urdf", chain())
    entries = (("l0", "l2", "Never"), ("l1", "l3", "Never"), ("l3", "bare", "Never"))
    path = write(tmp_path, "c.srdf", srdf(*entries))
    status, doc = audited(urdf, "--audit-srdf", path, *sweep)
    assert status == ExitStatus.OK
    assert [p["status"] for p in doc["audit"]["pairs"]] == ["never", "never", "never"]
    status, doc = audited(urdf, "--audit-srdf", path, "--sweep-budget", "1", *sweep)
    assert status == ExitStatus.OK and doc["summary"]["sweep_budget"] == 1
    found = {(p["a"], p["b"]): p["status"] for p in doc["audit"]["pairs"]}
    first = "undecided" if sweep else "never"
    assert found == {("l0", "l2"): first, ("l1", "l3"): "undecided", ("bare", "l3"): "never"}
    assert doc["summary"]["wrongly_disabled"] == 0


def test_the_audit_reads_the_sweep_when_there_is_one(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    status, doc = audited(urdf, "--audit-srdf", path, "--sweep")
    swept = {(p["a"], p["b"]): p for p in doc["sweeps"][0]["pairs"]}
    (pair,) = doc["audit"]["pairs"]
    assert status == ExitStatus.FAILED and swept["door", "stop"]["pose"] == pair["pose"]


def test_nothing_fails_with_fail_on_none_but_the_entry_is_listed(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    status, doc = audited(urdf, "--audit-srdf", path, "--fail-on", "none")
    (pair,) = doc["audit"]["pairs"]
    assert status == ExitStatus.OK and pair["wrong"] and not pair["failed"]


def test_a_wrong_entry_fails_a_run_of_passing_clash_tests_and_its_summary_says_why(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    args = (urdf, "--audit-srdf", path, "--test", "all:*:*:fail_on=duplicate")
    status, doc = audited(*args)
    assert status == ExitStatus.FAILED and doc["summary"]["failed_tests"] == []
    assert doc["summary"]["wrongly_disabled"] == 1 and not doc["summary"]["passed"]
    text = run_cli(*args).stdout.splitlines()
    assert text[-1].startswith("FAIL: ") and "wrongly disabled in the SRDF" in "".join(text[-2:])
    assert sum("door.srdf:3: door / stop" in line for line in text) == 1  # once, not per test


# ------------------------------------------------------------------------------------------
# Every format lists a wrong entry with its witness


def test_every_format_lists_the_wrong_entry_with_its_witness(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    result = check([urdf], config=None, cache_dir=None, jobs=1, motion={"audit": path})
    (pair,) = result.audit.pairs
    pose = f"hinge={pair.sweep.witness['hinge']:.9g}"
    text = render(result, "text")
    line = f"FAIL srdf sometimes (Never) door.srdf:3: door / stop interference at --pose {pose}"
    assert line in " ".join(text.split())
    assert text.endswith(
        "FAIL: 2 parts, 0 interference, 0 touching, 1 wrongly disabled in the SRDF\n"
    )
    assert json.loads(render(result, "json"))["audit"]["pairs"][0]["pose"] == pair.sweep.witness
    junit = render(result, "junit")
    assert 'line="3"' in junit and "disables a collision" in junit and pose in junit
    sarif = json.loads(render(result, "sarif"))
    sarif_validator().validate(sarif)
    (entry,) = sarif["runs"][0]["results"]
    assert entry["level"] == "error" and entry["properties"]["pose"] == pair.sweep.witness
    assert entry["locations"][0]["physicalLocation"]["region"] == {"startLine": 3}
    github = render(result, "github")
    assert f"::error file={path},line=3,title=meshcheck%3A SRDF disables a collision::" in github
    markdown = render(result, "markdown")
    assert "| FAIL sometimes | Never | 3 | door | stop |" in markdown and "hinge\\=" in markdown
    html = render(result, "html")
    data = json.loads(html.split('id="meshcheck-data">')[1].split("</script>")[0])
    (row,) = data["audit"]["rows"]
    assert row["failed"] and row["line"] == 3 and pose in row["pose"]


# ------------------------------------------------------------------------------------------
# The corrected SRDF


def test_the_corrected_srdf_drops_the_wrong_entry_and_passes_its_own_audit(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    text = srdf(("door", "stop", "Never"), ("frame", "door", "Adjacent"))
    text = text.replace("<robot", "<!-- keep me -->\n<robot")
    path = write(tmp_path, "door.srdf", text)
    out = tmp_path / "fixed.srdf"
    run = run_cli(urdf, "--audit-srdf", path, "--srdf", out)
    assert run.exit_code == ExitStatus.FAILED
    fixed = out.read_bytes()
    kept, removed = text.splitlines(keepends=True), fixed.decode().splitlines(keepends=True)
    assert [a for a, b in zip(kept, removed, strict=True) if a != b] == [kept[3]]
    assert removed[3].startswith("  <!-- meshcheck: removed door / stop (Never): interference")
    again = run_cli(urdf, "--audit-srdf", out)
    assert again.exit_code == ExitStatus.OK, again.output


def test_an_always_never_entry_is_corrected_and_an_undecided_one_kept(tmp_path, monkeypatch):
    """Two links welded into each other, disabled as Never: always (disabling is right, the
    reason becomes Always; the run passes). A pair the sweep cannot decide within its budget
    keeps its entry, a comment before it."""
    import meshcheck.sweep.search as search

    welded = door(STOP_ANGLE - 1e-3).replace(
        "</robot>",
        '<link name="weld"><collision><origin xyz="0.7 0.4 0"/><geometry>'
        '<box size="0.3 0.2 0.2"/></geometry></collision></link><joint name="w" type="fixed">'
        '<parent link="frame"/><child link="weld"/></joint></robot>',
    )
    urdf = write(tmp_path, "door.urdf", welded)
    path = write(tmp_path, "door.srdf", srdf(("stop", "weld", "Never"), ("door", "stop", "Never")))
    # the seeded samples, then one box: the whole range, too near the stop to be certified
    monkeypatch.setattr(search, "MAX_BOXES", search.SAMPLES + 1)
    settings_ = {"motion": {"audit": path}}
    result = check([urdf], config=None, cache_dir=None, jobs=1, **settings_)
    statuses = {(p.a, p.b): p.status for p in result.audit.pairs}
    assert statuses == {("stop", "weld"): "always", ("door", "stop"): "undecided"}
    assert result.passed
    fixed = corrected(result).decode()
    assert '<disable_collisions link1="stop" link2="weld" reason="Always"/>' in fixed
    assert (
        "<!-- meshcheck: door / stop (Never) not proven never within the sweep's box budget -->"
        ' <disable_collisions link1="door" link2="stop" reason="Never"/>'
    ) in fixed


def test_the_audited_srdf_is_never_written_over(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE - 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    run = run_cli(urdf, "--audit-srdf", path, "--srdf", path)
    assert run.exit_code == ExitStatus.USAGE and "is an input" in run.stderr
    assert open(path).read() == srdf(("door", "stop", "Never"))


# ------------------------------------------------------------------------------------------
# The SRDF as hostile input (in-process; the command line's one-line errors are in
# tests/test_hostile_robots.py)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ('<!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="&a;"/>', "document type"),
        ('<!DOCTYPE r SYSTEM "file:///etc/passwd"><robot/>', "document type"),
        ("<robot><disable_collisions", "not well-formed XML"),
        ("<model/>", "not <robot>: not an SRDF"),
        ('<robot><disable_collisions link1="a"/></robot>', "line 1: <disable_collisions> without"),
        ('<robot><disable_collisions link1="a" link2="a"/></robot>', "'a' against itself"),
        ("<robot>" + "<a>" * 100 + "</a>" * 100 + "</robot>", "levels deep"),
        ("<robot>" + "<g/>" * (MAX_SRDF_ELEMENTS + 1) + "</robot>", "elements"),
    ],
)
def test_a_bad_srdf_is_one_input_error_naming_it(text, reason):
    with pytest.raises(InputError, match=reason) as info:
        parse_srdf("x.srdf", text.encode())
    assert info.value.path == "x.srdf" and "\n" not in str(info.value)


def test_an_srdf_in_utf16_or_over_its_size_is_refused(tmp_path):
    path = tmp_path / "wide.srdf"
    path.write_bytes('<robot name="r"/>'.encode("utf-16"))
    with pytest.raises(InputError, match="UTF-16"):
        read_srdf(str(path))
    big = tmp_path / "big.srdf"
    with open(big, "wb") as fh:
        fh.truncate(17 << 20)
    with pytest.raises(InputError, match="over the limit"):
        read_srdf(str(big))


def test_unknown_links_are_named(tmp_path):
    urdf = write(tmp_path, "door.urdf", door(1.0))
    entries = [("door", f"ghost{k}", "Never") for k in range(7)] + [("stop", "door", "Never")]
    path = write(tmp_path, "door.srdf", srdf(*entries))
    run = run_cli(urdf, "--audit-srdf", path)
    assert run.exit_code == ExitStatus.INPUT
    assert run.stderr.strip().splitlines()[-1] == (
        f"error: {path}: disable_collisions names links {urdf} does not have: 'ghost0', "
        "'ghost1', 'ghost2', 'ghost3', 'ghost4' and 2 more"
    )


def test_entries_keep_their_place_in_the_file():
    text = b'<robot>\n  <disable_collisions link1="b" link2="a" reason=\'N"ever\'>'
    text += b'</disable_collisions>\n  <g><disable_collisions link1="c" link2="d"/></g></robot>'
    doc = parse_srdf("x.srdf", text)
    first, second = doc.pairs
    assert (first.a, first.b, first.reason, first.line) == ("a", "b", 'N"ever', 2)
    assert text[slice(*first.span)].endswith(b"></disable_collisions>")
    assert text[slice(*second.span)] == b'<disable_collisions link1="c" link2="d"/>'
    assert (second.reason, second.line) == ("", 3)


# ------------------------------------------------------------------------------------------
# moveit_resources' panda


@pytest.mark.filterwarnings("ignore::meshcheck.errors.MeshcheckWarning")
def test_the_pandas_srdf_against_python_fcl():
    """moveit_resources' panda SRDF disables 23 pairs as Never. The audit proves 22 and shows
    panda_link2 / panda_link6 colliding (python-fcl confirms the witness on the same meshes);
    no proven pair collides at 300 random poses."""
    result = check([PANDA], config=None, cache_dir=None, jobs=1, motion={"audit": PANDA_SRDF})
    audit = result.audit
    assert len(audit.pairs) == 23 and audit.unaudited == 11
    wrong = [p for p in audit.pairs if p.is_wrong]
    assert [(p.a, p.b) for p in wrong] == [("panda_link2", "panda_link6")]
    assert not result.passed
    oracle = read_robot(PANDA, PANDA_PACKAGE)
    assert collide(oracle, "panda_link2", "panda_link6", wrong[0].sweep.witness) is not None
    never = [(p.a, p.b) for p in audit.pairs if p.status == "never"]
    assert len(never) == 22
    from meshes import fcl_collide

    rng = np.random.default_rng(7)
    movable = oracle.movable
    for q in rng.uniform([j.lower for j in movable], [j.upper for j in movable], (300, 8)):
        poses = link_poses(oracle, {j.name: v for j, v in zip(movable, q, strict=True)})
        for a, b in never:
            assert not any(
                fcl_collide(ma, mb)
                for ma in posed(oracle, a, poses)
                for mb in posed(oracle, b, poses)
            ), (a, b, q)


@pytest.mark.browser
def test_the_html_header_shows_the_pose_and_the_audit(tmp_path, browser_page):
    page, errors = browser_page
    urdf = write(tmp_path, "door.urdf", door(STOP_ANGLE + 0.05))
    path = write(tmp_path, "door.srdf", srdf(("door", "stop", "Never")))
    out = tmp_path / "report.html"
    run = run_cli(urdf, "--audit-srdf", path, "--pose", "hinge=0.2", "--format", "html", "-o", out)
    assert run.exit_code == ExitStatus.FAILED
    open_report(page, out)
    assert "1 wrongly disabled in the SRDF" in page.locator("#counts").inner_text()
    assert page.locator("p.pose").all_inner_texts() == ["pose door.urdf: hinge=0.2"]
    assert page.locator("#audit").get_attribute("open") is not None
    (item,) = page.locator("#audit li").all_inner_texts()
    assert item.startswith("FAIL sometimes (Never) line 3: door / stop") and "hinge=" in item
    assert errors == []
