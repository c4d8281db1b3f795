"""Configuration: finding the file, strict validation, approvals, groups and --fail-on words."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshcheck.config import (
    Approval,
    Config,
    Groups,
    approval_reason,
    find_config,
    load_config,
    parse_fail_on,
)
from meshcheck.errors import ConfigError, ExitStatus

HYPOTHESIS = settings(derandomize=True, deadline=None, max_examples=50)

FULL = """
tolerance = 0.001
clearance = 0.2
threshold = 0.05
fail_on = ["interference", "touching"]

[[ignore]]
a = "frame.stl"
b = "bearing_*.stl"
reason = "press fit by design"

[[ignore]]
a = "*#pin"
b = "*#hub"
reason = "  keyed  "

[[ignore]]
id = "E0FFA4DD810D"
reason = "reviewed"

[groups]
a = ["frame.stl"]
b = "bolts/*"
"""


def test_full_meshcheck_toml(tmp_path):
    path = tmp_path / "meshcheck.toml"
    path.write_text(FULL)
    config = load_config(path)
    assert config == Config(
        path=str(path),
        tolerance=0.001,
        clearance=0.2,
        threshold=0.05,
        fail_on=("interference", "touching"),
        approvals=(
            Approval("frame.stl", "bearing_*.stl", "press fit by design"),
            Approval("*#pin", "*#hub", "keyed"),
            Approval(None, None, "reviewed", id="e0ffa4dd810d"),
        ),
        groups=Groups(("frame.stl",), ("bolts/*",)),
    )


def test_pyproject_reads_tool_meshcheck(tmp_path):
    path = tmp_path / "pyproject.toml"
    path.write_text('[project]\nname = "x"\n\n[tool.meshcheck]\nclearance = 1\n')
    assert load_config(path) == Config(path=str(path), clearance=1.0)


def test_empty_config_sets_nothing(tmp_path):
    path = tmp_path / "meshcheck.toml"
    path.write_text("")
    assert load_config(path) == Config(path=str(path))


def test_find_config_prefers_meshcheck_toml_then_walks_up(tmp_path):
    deep = tmp_path / "a" / "b"
    deep.mkdir(parents=True)
    (tmp_path / "meshcheck.toml").write_text("clearance = 1\n")
    (tmp_path / "a" / "pyproject.toml").write_text('[project]\nname = "no meshcheck table"\n')
    assert find_config(deep) == str(tmp_path / "meshcheck.toml")

    (tmp_path / "a" / "pyproject.toml").write_text("[tool.meshcheck]\nclearance = 2\n")
    assert find_config(deep) == str(tmp_path / "a" / "pyproject.toml")

    (tmp_path / "a" / "meshcheck.toml").write_text("clearance = 3\n")
    assert find_config(deep) == str(tmp_path / "a" / "meshcheck.toml")


def test_find_config_defaults_to_the_working_directory(tmp_path, monkeypatch):
    (tmp_path / "meshcheck.toml").write_text("")
    monkeypatch.chdir(tmp_path)
    assert find_config() == str(tmp_path / "meshcheck.toml")


INVALID = {
    "unknown key": ("tolerence = 1\n", "unknown key 'tolerence'"),
    "string number": ('clearance = "0.2"\n', "clearance must be a number"),
    "bool number": ("tolerance = true\n", "tolerance must be a number"),
    "negative": ("clearance = -1\n", "out of range"),
    "threshold range": ("threshold = 2\n", "out of range"),
    "nan tolerance": ("tolerance = nan\n", "tolerance must be a finite number"),
    "inf tolerance": ("tolerance = inf\n", "tolerance must be a finite number"),
    "inf clearance": ("clearance = inf\n", "clearance must be a finite number"),
    "fail_on none and more": ('fail_on = ["none", "touching"]\n', "'none' contradicts"),
    "bad toml": ("clearance = \n", "invalid TOML"),
    "fail_on word": ('fail_on = ["collision"]\n', "unknown fail-on status 'collision'"),
    "fail_on type": ("fail_on = 3\n", "fail_on must be a list of strings"),
    "ignore table": ('[ignore]\na = "x"\n', "ignore must be an array of tables"),
    "no reason": ('[[ignore]]\na = "x"\nb = "y"\n', "ignore entry 1 has no 'reason'"),
    "empty reason": ('[[ignore]]\na = "x"\nb = "y"\nreason = " "\n', "non-empty string"),
    "ignore key": (
        '[[ignore]]\na = "x"\nb = "y"\nreason = "r"\nstatus = "touching"\n',
        "unknown key 'status' in ignore entry 1 (known: a, b, id, reason)",
    ),
    "id and names": (
        '[[ignore]]\nid = "abc"\na = "x"\nb = "y"\nreason = "r"\n',
        "either id or a and b",
    ),
    "id without reason": ('[[ignore]]\nid = "abc"\n', "has no 'reason'"),
    "pattern type": ('[[ignore]]\na = 1\nb = "y"\nreason = "r"\n', "a must be a non-empty string"),
    "groups missing": ('[groups]\na = ["x"]\n', "groups.b must be"),
    "groups key": ('[groups]\na = ["x"]\nb = ["y"]\nc = ["z"]\n', "unknown key 'c' in groups"),
    "groups type": ("groups = 1\n", "groups must be a table"),
}


@pytest.mark.parametrize("case", sorted(INVALID))
def test_invalid_config_is_a_config_error_naming_the_file(tmp_path, case):
    text, reason = INVALID[case]
    path = tmp_path / "meshcheck.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.path == str(path)
    assert reason in info.value.reason
    assert info.value.exit_status == ExitStatus.USAGE


def test_invalid_pyproject_table_names_the_table(tmp_path):
    path = tmp_path / "pyproject.toml"
    path.write_text("[tool.meshcheck]\nclearence = 1\n")
    with pytest.raises(ConfigError, match=r"unknown key 'clearence' in \[tool.meshcheck\]"):
        load_config(path)


def test_missing_config_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot be read"):
        load_config(tmp_path / "nope.toml")


def test_parse_fail_on_accepts_comma_lists_and_repeats():
    assert parse_fail_on(["touching,interference", "touching", " clearance "]) == (
        "touching",
        "interference",
        "clearance",
    )
    assert parse_fail_on(["none"]) == ()
    assert parse_fail_on([]) is None
    with pytest.raises(ConfigError, match="'none' contradicts touching"):
        parse_fail_on(["none,touching"])
    with pytest.raises(ConfigError, match="unknown fail-on status 'overlap'"):
        parse_fail_on(["interference,overlap"])


def test_approval_matches_either_order():
    rules = [Approval("plate.stl", "bolt_*.stl", "washers omitted")]
    assert approval_reason(rules, "bolt_m8.stl", "plate.stl") == "washers omitted"
    assert approval_reason(rules, "plate.stl", "bolt_m8.stl") == "washers omitted"
    assert approval_reason(rules, "plate.stl", "bracket.stl") is None


def test_groups_allow_only_pairs_across():
    groups = Groups(("frame*",), ("bolt*", "nut*"))
    assert groups.allows("frame.stl", "bolt1.stl")
    assert groups.allows("nut2.stl", "frame.stl")
    assert not groups.allows("bolt1.stl", "nut2.stl")
    assert not groups.allows("frame.stl", "frame2.stl")


def test_default_tolerance_comes_from_the_pair():
    import numpy as np

    from meshcheck.tolerances import pair_tolerances, part_sizes

    lower = np.array([[0, 0, 0], [0, 0, 0], [50e3, 0, 0]], float)
    upper = np.array([[300, 400, 0], [3000, 4000, 0], [70e3, 10, 10]], float)
    diagonal, magnitude = part_sizes(lower, upper)
    tol = pair_tolerances(diagonal, magnitude, np.array([[0, 1], [1, 2]]))
    assert tol[0] == pytest.approx(5e-3)  # the smaller part's diagonal, not the assembly's
    assert tol[1] == 8 * np.spacing(np.float32(70e3))  # eight float32 steps at x = 70,000
    point = np.zeros((1, 3))
    assert pair_tolerances(*part_sizes(point, point), np.array([[0, 0]]))[0] > 0


names = st.text(alphabet="abc_.#/", min_size=1, max_size=8)


@HYPOTHESIS
@given(a=names, b=names, pa=st.sampled_from(["*", "a*", "*b", "?", "[ab]*"]), pb=names)
def test_approval_and_groups_are_symmetric(a, b, pa, pb):
    rule = Approval(pa, pb, "r")
    assert rule.matches(a, b) == rule.matches(b, a)
    groups = Groups((pa,), (pb,))
    assert groups.allows(a, b) == groups.allows(b, a)


# ------------------------------------------------------------------------------------------
# Through the Python API: options given to check() win over the file


def _two_overlapping_cubes(tmp_path):
    import trimesh

    a, b = tmp_path / "a.stl", tmp_path / "b.stl"
    trimesh.creation.box().export(str(a))
    trimesh.creation.box().apply_translation((0.9, 0, 0)).export(str(b))
    return a, b


def test_check_applies_the_config_file(tmp_path):
    from meshcheck.pipeline import check

    a, b = _two_overlapping_cubes(tmp_path)
    config = tmp_path / "meshcheck.toml"
    config.write_text(f'tolerance = 0.2\n[[ignore]]\na = "{a}"\nb = "*b.stl"\nreason = "shim"\n')
    result = check([a, b], config=config)
    (finding,) = result.findings
    assert result.tolerance == 0.2
    assert (finding.a, finding.b) == (str(a), str(b))
    assert (finding.status, finding.approval_reason) == ("touching", "shim")  # 0.1 overlap < 0.2

    explicit = check([a, b], config=config, tolerance=0.01)
    assert explicit.tolerance == 0.01
    assert [(f.status, f.approval_reason) for f in explicit.findings] == [("interference", "shim")]

    from meshcheck.errors import MeshcheckWarning

    with pytest.warns(MeshcheckWarning, match="nothing to compare"):
        plain = check(str(a))  # one path as a string is one part, not one per character
    assert [p.name for p in plain.parts] == [str(a)]


def test_check_approves_findings_by_stable_id(tmp_path):
    import trimesh

    from meshcheck.pipeline import check

    a, b = _two_overlapping_cubes(tmp_path)
    (finding,) = check([a, b]).findings
    config = load_config_text(tmp_path, f'[[ignore]]\nid = "{finding.id}"\nreason = "ok"\n')
    assert [f.approval_reason for f in check([a, b], config=config).findings] == ["ok"]
    # the ID hashes the meshes: once a part changes, the approval no longer applies
    trimesh.creation.box().apply_translation((0.8, 0, 0)).export(str(b))
    (moved,) = check([a, b], config=config).findings
    assert moved.id != finding.id
    assert moved.approval_reason is None


def test_check_groups_from_config_skip_other_pairs(tmp_path):
    import trimesh

    from meshcheck.pipeline import check

    a, b = _two_overlapping_cubes(tmp_path)
    c = tmp_path / "c.stl"
    trimesh.creation.box().apply_translation((5, 0, 0)).export(str(c))
    config = load_config_text(tmp_path, '[groups]\na = ["*a.stl"]\nb = ["*c.stl"]\n')
    assert check([a, b, c], config=config).findings == []
    assert len(check([a, b, c]).findings) == 1


def load_config_text(tmp_path, text):
    path = tmp_path / "meshcheck.toml"
    path.write_text(text)
    return load_config(path)
