"""Hostile robots: a URDF that names files outside its folders, an SRDF built to hurt.

Every case runs the command in a subprocess, capped in wall time (``timeout``) and address
space (``RLIMIT_AS``), and checks the exit status, that stderr's last line is the one error
line naming the file, that it took under 60 s and a peak of under 2 GiB (read in ``/proc``:
Linux), and that nothing outside the inputs, the outputs and the cache was opened: the child
records every file it opens (``sys.addaudithook``, Python's ``open`` event, which every reader
of meshcheck goes through) and what it opened for writing. The one kind of file read above the
inputs is a ``package.xml``: the package search ROS describes (``load.urdf.package_roots``)
reads the name each declares, and nothing else of those folders unless the name is the
package's.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest
from meshes import box
from test_urdf import outside_layout

from meshcheck.errors import ExitStatus

#: The address space a run may take (numpy, scipy, numba and trimesh map ~1.5 GiB at import).
MEMORY_CAP = 3 << 30

# The child records what it opens (path, whether for writing) and its peak memory at exit.
_WATCH = """
import atexit, json, os, runpy, sys
record = sys.argv.pop(1)
opened = []
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes)):
        path = os.fsdecode(args[0])
        mode, flags = args[1] or "", args[2] or 0
        writes = any(c in mode for c in "wax+") or bool(flags & (os.O_WRONLY | os.O_RDWR))
        opened.append((os.path.abspath(path), writes))
def done():
    peak = 0
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                peak = int(line.split()[1])
    with open(record, "w") as fh:
        json.dump({"opened": opened, "peak_kib": peak}, fh)
atexit.register(done)
sys.addaudithook(hook)
sys.argv[0] = "meshcheck"
runpy.run_module("meshcheck", run_name="__main__")
"""


def _cap():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def watched(tmp_path, args, *, allowed=()) -> tuple[int, list[str]]:
    """Run ``meshcheck ARGS`` (cache in ``tmp_path/cache``, its key from the environment, the
    state folder in ``tmp_path/state``) in a capped subprocess; assert it
    took under 60 s and 2 GiB and opened nothing outside the Python installation, ``/proc``,
    ``/dev/null`` and ``tmp_path`` but its ``allowed`` paths, and wrote only inside
    ``tmp_path``; return (exit status, stderr lines)."""
    record = tmp_path / "opened.json"
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-c", _WATCH, str(record), *map(str, args), "--no-config", "-j", "1",
         "--cache-dir", str(tmp_path / "cache")],
        capture_output=True,
        timeout=120,
        preexec_fn=_cap,
        env={**os.environ, "XDG_STATE_HOME": str(tmp_path / "state"),
             "MESHCHECK_CACHE_SECRET": "hostile robots"},
        check=False,
    )  # fmt: skip
    seconds = time.monotonic() - start
    lines = [
        line
        for line in proc.stderr.decode(errors="replace").splitlines()
        if not line.startswith("meshcheck: ")  # progress, on a slow start
    ]
    assert not any("Traceback" in line for line in lines), lines
    assert seconds < 60, seconds
    doc = json.loads(record.read_text())
    assert doc["peak_kib"] < 2 << 20, doc["peak_kib"]
    installed = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, *sys.path) if p}
    root = os.path.realpath(tmp_path)
    outside = []
    for path, writes in doc["opened"]:
        real = os.path.realpath(path)
        if path == str(record) or real in allowed:
            continue
        if writes and not real.startswith(root + os.sep):
            outside.append((path, "written"))
        elif not (
            real.startswith(root + os.sep)
            or os.path.basename(real) == "package.xml"  # the package search (load.urdf)
            or real.startswith(("/proc/", "/sys/", "/dev/"))
            or any(real.startswith(p + os.sep) for p in installed)
        ):
            outside.append((path, "read"))
    assert outside == [], outside
    return proc.returncode, lines


def one_error(lines, status, code, path, *needles) -> str:
    """Assert exit ``code`` and that stderr's last line is the error naming ``path``."""
    assert status == code, lines
    assert lines and lines[-1].startswith(f"error: {path}: "), lines
    for needle in needles:
        assert needle in lines[-1], lines
    return lines[-1]


def robot_with_mesh(filename: str) -> str:
    return f"""<robot name="r">
  <link name="base"><collision><geometry><box size="1 1 1"/></geometry></collision></link>
  <link name="arm"><collision><geometry><mesh filename="{filename}"/></geometry></collision>
  </link>
  <joint name="j" type="fixed"><origin xyz="3 0 0"/><parent link="base"/><child link="arm"/>
  </joint>
</robot>"""


def workspace(tmp_path) -> tuple[str, str]:
    """``test_urdf.outside_layout``: (package folder, secret mesh outside the workspace)."""
    where = outside_layout(tmp_path)
    return where["pkg"], where["secret"]


def write_robot(folder: str, filename: str) -> str:
    """``folder/r.urdf``, a robot whose arm is the mesh ``filename``; its path."""
    urdf = os.path.join(folder, "r.urdf")
    with open(urdf, "w") as fh:
        fh.write(robot_with_mesh(filename))
    return urdf


# ------------------------------------------------------------------------------------------
# A URDF reads nothing outside its folder, its package and the package paths


@pytest.mark.linux_only
@pytest.mark.posix_only
@pytest.mark.parametrize(
    ("filename", "reason"),
    [
        ("package://pkg/../../../../etc/hostname", "leads outside package 'pkg'"),
        ("package://pkg/../../../secret/key.stl", "leads outside package 'pkg'"),
        ("../../../../secret/key.stl", "outside the URDF's folder"),
        ("SECRET", "outside the URDF's folder"),
        ("file://SECRET", "outside the URDF's folder"),
        ("file:///etc/passwd", "outside the URDF's folder"),
    ],
)
def test_a_mesh_outside_the_robots_folders_is_refused(tmp_path, filename, reason):
    pkg, secret = workspace(tmp_path)
    urdf = write_robot(os.path.join(pkg, "urdf"), filename.replace("SECRET", secret))
    status, lines = watched(tmp_path, [urdf], allowed={os.path.realpath(urdf)})
    one_error(lines, status, ExitStatus.INPUT, urdf, reason, "--allow-outside-paths")
    assert len(lines) == 1, lines


@pytest.mark.linux_only
@pytest.mark.posix_only
def test_a_symbolic_link_out_of_the_package_is_refused(tmp_path):
    pkg, secret = workspace(tmp_path)
    os.symlink(secret, os.path.join(pkg, "meshes", "link.stl"))
    urdf = write_robot(os.path.join(pkg, "urdf"), "package://pkg/meshes/link.stl")
    status, lines = watched(tmp_path, [urdf])
    one_error(lines, status, ExitStatus.INPUT, urdf, "leads outside package 'pkg'")


@pytest.mark.linux_only
@pytest.mark.posix_only
def test_a_folder_above_named_like_the_package_is_not_searched(tmp_path):
    """``package://home/...`` from a URDF below a folder named ``home`` (as /home is above
    every runner's checkout): no package.xml names it, so nothing there is read."""
    robot = tmp_path / "home" / "repo"
    robot.mkdir(parents=True)
    box().export(tmp_path / "home" / "key.stl")
    urdf = write_robot(str(robot), "package://home/key.stl")
    status, lines = watched(tmp_path, [urdf])
    one_error(lines, status, ExitStatus.INPUT, urdf, "not found in package 'home'")


@pytest.mark.linux_only
@pytest.mark.posix_only
def test_allow_outside_paths_reads_what_the_user_allows(tmp_path):
    pkg, secret = workspace(tmp_path)
    urdf = write_robot(os.path.join(pkg, "urdf"), secret)
    status, lines = watched(tmp_path, [urdf, "--allow-outside-paths"])
    assert status == ExitStatus.OK, lines
    status, lines = watched(tmp_path, [urdf, "--package-path", os.path.dirname(secret)])
    assert status == ExitStatus.OK, lines  # a folder the command line names is the robot's


# ------------------------------------------------------------------------------------------
# An SRDF to audit is as hostile as any XML


def door_urdf(tmp_path) -> str:
    path = tmp_path / "door.urdf"
    path.write_text(
        '<robot name="door"><link name="frame"><collision><geometry><box size="0.1 0.1 0.1"/>'
        '</geometry></collision></link><link name="door"><collision><origin xyz="0.5 0 0"/>'
        '<geometry><box size="1 0.1 0.2"/></geometry></collision></link><joint name="hinge" '
        'type="revolute"><parent link="frame"/><child link="door"/><axis xyz="0 0 1"/>'
        '<limit lower="-0.5" upper="0.5"/></joint></robot>'
    )
    return str(path)


def _laughs() -> str:
    entities = ['<!ENTITY l0 "lol">'] + [
        f'<!ENTITY l{k} "{("&l" + str(k - 1) + ";") * 10}">' for k in range(1, 10)
    ]
    return f'<!DOCTYPE robot [{"".join(entities)}]><robot name="&l9;"/>'


def _srdf_cases(folder) -> dict:
    cases = {
        "billion-laughs": (_laughs(), "refused: entity expansion"),
        "external-entity": ('<!DOCTYPE r SYSTEM "file:///etc/passwd"><robot/>', "document type"),
        "elements": ("<robot>" + "<g/>" * 200_001 + "</robot>", "more than 200000 elements"),
        "unknown-links": (
            '<robot><disable_collisions link1="door" link2="../../etc" reason="Never"/></robot>',
            "names links",
        ),
        "not-an-srdf": ("<html/>", "not <robot>"),
    }
    out = {}
    for name, (text, reason) in cases.items():
        path = folder / f"{name}.srdf"
        path.write_text(text)
        out[name] = (path, reason)
    sparse = folder / "sparse.srdf"
    with open(sparse, "wb") as fh:
        fh.truncate(3 << 30)  # 3 GB of holes: no disk used
    out["sparse"] = (sparse, "over the limit")
    fifo = folder / "fifo.srdf"
    os.mkfifo(fifo)
    out["fifo"] = (fifo, "not a regular file")
    out["/dev/zero"] = ("/dev/zero", "not a regular file")
    return out


@pytest.mark.linux_only
@pytest.mark.posix_only
@pytest.mark.parametrize(
    "case",
    ["billion-laughs", "external-entity", "elements", "unknown-links", "not-an-srdf", "sparse",
     "fifo", "/dev/zero"],
)  # fmt: skip
def test_a_hostile_srdf_is_one_line_exit_3(tmp_path, case):
    path, reason = _srdf_cases(tmp_path)[case]
    status, lines = watched(tmp_path, [door_urdf(tmp_path), "--audit-srdf", path])
    one_error(lines, status, ExitStatus.INPUT, str(path), reason)
    assert len(lines) == 1, lines


@pytest.mark.linux_only
@pytest.mark.posix_only
def test_an_audit_of_a_bad_entry_reads_and_writes_nothing_else(tmp_path):
    """The wrong entry fails the run (exit 1); the corrected SRDF is the one file written
    besides the cache."""
    srdf = tmp_path / "door.srdf"
    srdf.write_text(
        '<robot><disable_collisions link1="frame" link2="door" reason="Never"/></robot>'
    )
    out = tmp_path / "out.srdf"
    status, lines = watched(
        tmp_path,
        [door_urdf(tmp_path), "--audit-srdf", srdf, "--audit-reasons", "all", "--srdf", out],
    )
    assert status == ExitStatus.FAILED, lines
    assert "meshcheck: removed door / frame (Never)" in out.read_text()
