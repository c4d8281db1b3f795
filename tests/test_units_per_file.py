"""A file's own unit: ``--units FILE=UNIT`` and the configuration's ``[units]`` table
win over what a file declares, and implausible sizes warn with the fix."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from meshes import box

from meshcheck import check
from meshcheck.cli import main
from meshcheck.errors import ConfigError, MeshcheckWarning
from meshcheck.load import load_bodies
from meshcheck.units import UnitRule, given_units, unit_rule


def write_engine(folder, shift: float = 600.0) -> tuple[str, str]:
    """A 600 x 300 x 300 mm engine block exported to GLB in millimetres (glTF says metres: it
    reads as 735 m across) and a millimetre STL bracket that really cuts 10 mm into it."""
    engine = trimesh.creation.box((600.0, 300.0, 300.0))
    engine.apply_translation((300.0 + shift, 150.0, 150.0))  # x from 600 to 1200
    scene = trimesh.Scene()
    scene.add_geometry(engine, node_name="engine", geom_name="engine")
    glb = os.path.join(folder, "engine.glb")
    scene.export(glb)
    bracket = os.path.join(folder, "bracket.stl")
    box((100.0, 20.0, 20.0), at=(640.0 + shift, 150.0, 150.0)).export(bracket)  # 1190 to 1290
    return glb, bracket


def run(args, cwd=None):
    """The command in-process: (exit status, stdout, stderr lines without progress)."""
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        result = CliRunner().invoke(main, [*map(str, args), "--no-cache", "-j", "1"])
    finally:
        os.chdir(old)
    assert "Traceback" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    lines = [x for x in result.stderr.splitlines() if not x.startswith("meshcheck: ")]
    return result.exit_code, result.stdout, lines


# ------------------------------------------------------------------------------------------
# Known answers


def test_a_millimetre_gltf_warns_as_743_m_and_passes_silently_no_more(tmp_path):
    write_engine(tmp_path)
    code, out, err = run(["engine.glb", "bracket.stl", "--format", "json"], cwd=tmp_path)
    assert code == 0  # read in metres the engine is far from the bracket: nothing to see
    (warning,) = [line for line in err if "implausible" in line]
    assert warning.startswith("warning: engine.glb: is 7.348e+05 mm across, read in m:")
    assert warning.endswith("give --units engine.glb=mm")
    assert warning in [f"warning: {w}" for w in json.loads(out)["summary"]["warnings"]]

    code, out, err = run(
        ["engine.glb", "bracket.stl", "--units", "engine.glb=mm", "--format", "json"],
        cwd=tmp_path,
    )
    doc = json.loads(out)
    assert code == 1, err
    (finding,) = doc["results"]
    assert finding["status"] == "interference"
    assert finding["depth"] == pytest.approx(10.0, abs=1e-3)
    assert doc["summary"]["units"] == "mm"
    assert not [line for line in err if line.startswith("warning:")], err


def test_the_file_unit_wins_over_what_gltf_3mf_and_the_report_unit_say(tmp_path):
    glb, _ = write_engine(tmp_path)
    (alone,) = load_bodies([glb], file_units=[UnitRule(glb, "mm")])
    assert alone.units == "mm"  # the file's unit given counts as what it declares
    np.testing.assert_allclose(alone.world.extents, [600, 300, 300])
    (inches,) = load_bodies([glb], units="in", file_units=[UnitRule(glb, "mm")])
    assert inches.units == "in"
    np.testing.assert_allclose(inches.world.extents, np.array([600, 300, 300]) / 25.4)
    model = (
        '<model unit="inch" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
        '<resources><object id="1" type="model"><mesh><vertices>'
        + "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in box().vertices)
        + "</vertices><triangles>"
        + "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in box().faces)
        + '</triangles></mesh></object></resources><build><item objectid="1"/></build></model>'
    )
    threemf = tmp_path / "part.3mf"
    import zipfile

    with zipfile.ZipFile(threemf, "w") as z:
        z.writestr("3D/3dmodel.model", model)
    (declared,) = load_bodies([str(threemf)])
    (given,) = load_bodies([str(threemf)], file_units=[UnitRule("*.3mf", "cm")])
    assert (declared.units, given.units) == ("in", "cm")
    np.testing.assert_allclose(given.world.extents, [1, 1, 1])


@pytest.mark.posix_only
def test_files_are_named_by_path_real_path_or_glob_and_the_last_rule_wins(tmp_path):
    (tmp_path / "cad").mkdir()
    a, b = tmp_path / "cad" / "a.glb", tmp_path / "cad" / "b.glb"
    write_engine(tmp_path / "cad")
    os.rename(tmp_path / "cad" / "engine.glb", a)
    os.link(a, b)
    link = tmp_path / "link.glb"
    os.symlink(a, link)
    paths = [str(a), str(b), "cad/a.glb"]
    assert UnitRule(str(link), "mm").matches(str(a))  # the same real file
    assert not UnitRule(str(link), "mm").matches(str(b))  # a hard link is another path
    rules = [UnitRule("cad/*", "mm"), unit_rule(f"{b}=in")]
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert given_units(paths, rules) == {str(a): "mm", str(b): "in", "cad/a.glb": "mm"}
        # configuration rules are relative to the configuration file's folder
        base = UnitRule("a.glb", "cm", base=str(tmp_path / "cad"))
        assert given_units(["cad/a.glb", "cad/b.glb"], [base]) == {"cad/a.glb": "cm"}
        # a directory names every file below it, as a directory argument does
        assert given_units(["cad/a.glb", str(link)], [UnitRule("cad", "m")]) == {
            "cad/a.glb": "m",
            str(link): "m",  # its real path is below cad/
        }
    finally:
        os.chdir(old)


def test_config_units_table_is_relative_to_its_folder(tmp_path):
    project = tmp_path / "project"
    (project / "cad").mkdir(parents=True)
    write_engine(project / "cad")
    (project / "meshcheck.toml").write_text(
        'hide_touching = true\n[units]\n"cad/*.glb" = "millimetre"\n'
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    code, out, err = run(
        [
            "../project/cad/engine.glb",
            "../project/cad/bracket.stl",
            "--config",
            "../project/meshcheck.toml",
            "--format",
            "json",
        ],
        cwd=elsewhere,
    )
    assert code == 1, err
    assert json.loads(out)["results"][0]["depth"] == pytest.approx(10.0, abs=1e-3)
    # the command line's rule comes after the file's, and wins
    code, _, err = run(
        [
            "../project/cad/engine.glb",
            "../project/cad/bracket.stl",
            "--config",
            "../project/meshcheck.toml",
            "--units",
            "*.glb=m",
        ],
        cwd=elsewhere,
    )
    assert code == 0, err  # read in metres: the engine is 600 m away from the bracket
    assert not any("implausible" in line for line in err), err  # the user said metres


def test_a_stale_config_units_entry_warns(tmp_path):
    write_engine(tmp_path)
    (tmp_path / "meshcheck.toml").write_text('[units]\n"gone.glb" = "mm"\n"*.glb" = "mm"\n')
    code, _, err = run(["engine.glb", "bracket.stl"], cwd=tmp_path)
    assert code == 1
    assert any("'gone.glb' names no input file" in line for line in err), err


def test_finding_ids_and_the_pair_cache_follow_the_file_unit(tmp_path):
    """A report is a function of the inputs and options: the same run from a warm cache filled by
    a run with another unit gives the cold answer, and the unit that moves a part moves its ID."""
    glb, bracket = write_engine(tmp_path, shift=0.0)  # the bracket from x = 590 to 690 mm
    cache = str(tmp_path / "cache")
    mm = check([glb, bracket], file_units={glb: "mm"}, cache_dir=cache, config=None)
    cm = check([glb, bracket], file_units={glb: "cm"}, cache_dir=cache, config=None)
    cold = check([glb, bracket], file_units={glb: "cm"}, use_cache=False, config=None)
    assert [f.to_dict() for f in cm.findings] == [f.to_dict() for f in cold.findings]
    (f_mm,) = mm.findings
    (f_cm,) = cm.findings  # the engine 6 m long now: the bracket is buried in it
    assert f_mm.id != f_cm.id
    assert f_mm.depth == pytest.approx(10.0, abs=1e-3)
    assert f_cm.depth == pytest.approx(20.0, abs=1e-3)


# ------------------------------------------------------------------------------------------
# Implausible sizes


def test_a_part_of_micrometres_warns_with_the_fix(tmp_path):
    frame = tmp_path / "frame.stl"
    box((400, 400, 20)).export(frame)
    bolt = tmp_path / "bolt.stl"
    box((0.006, 0.006, 0.02), at=(0, 0, 0.02)).export(bolt)  # a 20 mm bolt written in metres
    with pytest.warns(MeshcheckWarning) as caught:
        load_bodies([str(frame), str(bolt)])
    (message,) = [str(w.message) for w in caught]
    assert message.startswith(f"{bolt}: is 0.02173 mm across, read in mm: micrometres")
    assert message.endswith(f"give --units {bolt}=m")
    load_bodies([str(frame), str(bolt)], file_units=[UnitRule(str(bolt), "m")])  # no warning


def test_a_mm_gltf_beside_a_mm_stl_at_196x_now_warns(tmp_path):
    """The issue's case: a millimetre glTF part (read in metres) 196 times the size of the
    millimetre STL beside it, under the 500x rule of files read in one unit."""
    small = tmp_path / "pin.glb"
    scene = trimesh.Scene()
    scene.add_geometry(box((11.316, 11.316, 11.316)), node_name="pin")  # 19.6 mm, or 19.6 m
    scene.export(small)
    frame = tmp_path / "frame.stl"
    box((57.735, 57.735, 57.735)).export(frame)  # 100 mm across
    with pytest.warns(MeshcheckWarning, match="mixed units") as caught:
        load_bodies([str(small), str(frame)])
    (message,) = [str(w.message) for w in caught]
    assert message.startswith(f"{small}: is 196 times the size of {frame}")
    assert "read in m and mm" in message and "--units FILE=UNIT" in message


def test_a_file_whose_unit_is_given_is_never_warned_about(tmp_path):
    small = tmp_path / "pin.glb"
    scene = trimesh.Scene()
    scene.add_geometry(box((11.316, 11.316, 11.316)), node_name="pin")
    scene.export(small)
    frame = tmp_path / "frame.stl"
    box((57.735, 57.735, 57.735)).export(frame)
    load_bodies([str(small), str(frame)], file_units=[UnitRule(str(small), "m")])  # no warning


def test_same_unit_files_keep_the_500x_rule(tmp_path):
    a, b = tmp_path / "a.stl", tmp_path / "b.stl"
    box((400, 400, 400)).export(a)
    box((2, 1, 1)).export(b)  # 283 times smaller: a 0.4 m frame and its pin, both mm
    load_bodies([str(a), str(b)])  # no warning (filterwarnings = error)


# ------------------------------------------------------------------------------------------
# Hostile: one line, exit 2, in a capped subprocess


def capped(args, cwd) -> tuple[int, list[str]]:
    code = (
        "import resource, runpy, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))\n"
        "sys.argv[0] = 'meshcheck'\n"
        "runpy.run_module('meshcheck', run_name='__main__')\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, *args, "--no-cache", "--no-config"],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    lines = [x for x in proc.stderr.splitlines() if not x.startswith("meshcheck: ")]
    return proc.returncode, lines


@pytest.mark.posix_only
@pytest.mark.parametrize(
    ("units", "line"),
    [
        ("engine.glb=furlong", "error: engine.glb: --units: unknown length unit 'furlong'"),
        ("furlong", "error: --units: unknown length unit 'furlong'"),
        ("engine.glb=", "error: engine.glb: --units: 'engine.glb=' is not FILE=UNIT"),
        ("motor.glb=mm", "error: motor.glb: --units: names no input file (the inputs are"),
        ("*.step=mm", "error: *.step: --units: names no input file"),
    ],
)
def test_bad_file_units_are_one_line_and_exit_2(tmp_path, units, line):
    write_engine(tmp_path)
    code, err = capped(["engine.glb", "bracket.stl", "--units", units], tmp_path)
    assert code == 2
    assert len(err) == 1 and err[0].startswith(line), err


@pytest.mark.posix_only
def test_a_urdf_robot_takes_no_unit(tmp_path):
    (tmp_path / "robot.urdf").write_text(
        '<robot name="r"><link name="base"><collision><geometry><box size="1 1 1"/>'
        "</geometry></collision></link></robot>"
    )
    code, err = capped(["robot.urdf", "--units", "robot.urdf=mm"], tmp_path)
    assert code == 2
    assert err == [
        "error: robot.urdf: a URDF robot takes no unit (--units, [units]): it is in metres "
        "(ROS); give its meshes' unit with their scale attribute"
    ]


def test_bad_units_tables_are_config_errors(tmp_path):
    from meshcheck.config import load_config

    for text, reason in [
        ('[units]\n"a.glb" = "furlong"\n', "unknown length unit 'furlong'"),
        ('[units]\n"a.glb" = 3\n', "must be a unit such as"),
        ("units = 3\n", "units must be a unit"),
        ('quiet = "yes"\n', "quiet must be true or false"),
    ]:
        path = tmp_path / "meshcheck.toml"
        path.write_text(text)
        with pytest.raises(ConfigError, match=reason):
            load_config(path)


def test_a_step_file_given_another_unit_is_rescaled_and_left_out_of_the_brep_check():
    step = os.path.join(os.path.dirname(__file__), "..", "sample_meshes", "assembly.step")
    mm = check([step], use_cache=False, config=None)
    cm = check([step], units="mm", file_units={step: "cm"}, use_cache=False, config=None)
    assert (mm.units, cm.units) == ("mm", "mm")
    assert all(b.is_rescaled for b in cm.bodies) and not any(b.is_rescaled for b in mm.bodies)
    (deep_mm,) = [f for f in mm.findings if f.status == "interference"]
    (deep_cm,) = [f for f in cm.findings if f.status == "interference"]
    assert deep_mm.depth == pytest.approx(0.70, abs=0.01)
    assert deep_cm.depth == pytest.approx(7.0, abs=0.1)  # ten times: the file is in cm
    extents = [np.ptp(b.world.vertices, axis=0) for b in (mm.bodies[0], cm.bodies[0])]
    np.testing.assert_allclose(extents[1], 10 * extents[0], rtol=1e-3)


def test_pyproject_units_table(tmp_path):
    from meshcheck.config import load_config

    path = tmp_path / "pyproject.toml"
    path.write_text('[tool.meshcheck]\nquiet = true\n[tool.meshcheck.units]\n"cad/*.glb" = "mm"\n')
    config = load_config(path)
    assert config.units is None and config.quiet is True
    assert config.file_units == (UnitRule("cad/*.glb", "mm", str(tmp_path), str(path)),)
