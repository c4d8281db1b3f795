"""Hostile inputs: no wrong PASS, no hang, no crash that reads as a bug.

Every case that runs the command runs it in a subprocess with a wall-time cap (``timeout``) and
an address-space cap (``RLIMIT_AS``), and checks the exit status and that stderr's last line is
the one error line. Servers the tests start listen on 127.0.0.1 only and are stopped by process
id (or closed, for a socket this process holds).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import step_writer
import test_hostile_inputs as hostile_inputs
from meshes import box

from meshcheck.errors import ExitStatus

CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"

#: The address space a run may take (numpy, scipy, numba and trimesh map ~1.5 GiB of it at import).
MEMORY_CAP = 3 << 30


def _cap_memory(limit: int = MEMORY_CAP):
    def apply():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return apply


def run(args, *, cwd=None, seconds: float = 240, env=None, cache: bool = False, memory=MEMORY_CAP):
    """``python -m meshcheck ARGS`` in a capped subprocess: (exit status, stdout, stderr lines)."""
    extra = [] if cache else ["--no-cache"]
    proc = subprocess.run(
        [sys.executable, "-m", "meshcheck", *map(str, args), *extra],
        capture_output=True,
        timeout=seconds,
        cwd=cwd,
        env={**os.environ, **(env or {})},
        preexec_fn=_cap_memory(memory),
        check=False,
    )
    lines = proc.stderr.decode(errors="replace").splitlines()
    assert not any("Traceback" in line for line in lines), lines
    return proc.returncode, proc.stdout.decode(errors="replace"), lines


def mesh_xml(mesh) -> str:
    coords = mesh.vertices.tolist()
    verts = "".join(f'<vertex x="{x!r}" y="{y!r}" z="{z!r}"/>' for x, y, z in coords)
    tris = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in mesh.faces)
    return f"<mesh><vertices>{verts}</vertices><triangles>{tris}</triangles></mesh>"


def write_3mf(path, build: str, mesh=None) -> str:
    import zipfile

    objects = f'<object id="1" name="cube">{mesh_xml(mesh or box())}</object>'
    model = f'<model xmlns="{CORE}" unit="millimeter"><resources>{objects}</resources>'
    model += f"<build>{build}</build></model>"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", model)
    return str(path)


def gltf_doc(nodes: list[dict]) -> dict:
    """A glTF holding one unit cube (float32 positions, metres), placed by ``nodes``, all of
    them roots of the scene (``test_hostile_inputs.gltf_doc``)."""
    return hostile_inputs.gltf_doc(nodes, list(range(len(nodes))))


def write_gltf(path, nodes: list[dict]) -> str:
    path.write_text(json.dumps(gltf_doc(nodes)))
    return str(path)


def one_error(lines, status, code, *needles) -> str:
    """Assert exit ``code`` and that stderr's last line is the error holding ``needles``."""
    assert status == code, lines
    assert lines and lines[-1].startswith("error: "), lines
    for needle in needles:
        assert needle in lines[-1], lines
    return lines[-1]


# ------------------------------------------------------------------------------------------
# Wrong PASS 1: a singular or non-finite placement is exit 3, naming the file and the node


@pytest.mark.posix_only
def test_3mf_item_scaled_to_zero_is_refused(tmp_path):
    # 0.2: the collapsed cube dropped out of the check, exit 0
    build = '<item objectid="1"/><item objectid="1" transform="0 0 0 0 0 0 0 0 0 0.5 0.2 0.1"/>'
    path = write_3mf(tmp_path / "flat.3mf", build)
    status, _, lines = run([path])
    one_error(lines, status, ExitStatus.INPUT, f"{path}#cube", "singular")


@pytest.mark.posix_only
@pytest.mark.parametrize(
    "node",
    [
        {"scale": [0.0, 0.0, 0.0], "translation": [0.5, 0.2, 0.1]},
        {"scale": [1.0, 0.0, 1.0]},
        {"matrix": [0.0] * 12 + [0.5, 0.2, 0.1, 1.0]},
    ],
    ids=["zero-scale", "flat-scale", "zero-matrix"],
)
def test_gltf_singular_node_is_refused(tmp_path, node):
    path = write_gltf(tmp_path / "flat.gltf", [{"mesh": 0, "name": "base"}, {"mesh": 0, **node}])
    status, _, lines = run([path])
    one_error(lines, status, ExitStatus.INPUT, f"{path}#1", "singular")


def test_singular_placement_is_refused_in_the_library(tmp_path):
    from meshcheck.errors import InputError
    from meshcheck.load import load_bodies

    item = '<item objectid="1" transform="0 0 0 0 0 0 0 0 0 1 1 1"/>'
    path = write_3mf(tmp_path / "flat.3mf", item)
    with pytest.raises(InputError) as info:
        load_bodies([path])
    assert info.value.path == path
    assert "singular" in info.value.reason


@pytest.mark.posix_only
def test_gltf_zero_quaternion_is_refused(tmp_path):
    # 0.2: trimesh read a zero rotation as no rotation, placing the part where nobody put it
    nodes = [{"mesh": 0, "name": "base"}, {"mesh": 0, "rotation": [0.0, 0.0, 0.0, 0.0]}]
    path = write_gltf(tmp_path / "q.gltf", nodes)
    status, _, lines = run([path])
    one_error(lines, status, ExitStatus.INPUT, path, "node 1", "not a unit quaternion")


# ------------------------------------------------------------------------------------------
# Wrong PASS 2: a finding's ID changes when either part moves


def _clash(tmp_path, name: str, overlap: float) -> str:
    """A glTF of two unit cubes (metres), the second moved so they overlap by ``overlap``."""
    nodes = [
        {"mesh": 0, "name": "base"},
        {"mesh": 0, "name": "pin", "translation": [1 - overlap, 0, 0]},
    ]
    folder = tmp_path / name
    folder.mkdir()
    return write_gltf(folder / "asm.gltf", nodes)


@pytest.mark.posix_only
def test_moving_a_node_changes_the_finding_id_and_lapses_approval_and_baseline(tmp_path):
    # 0.2: a 0.01 m clash moved to 0.9 m kept its ID: approved by ID and "active" in the baseline
    small, big = _clash(tmp_path, "small", 0.01), _clash(tmp_path, "big", 0.9)
    status, out, lines = run(["asm.gltf", "--format", "json"], cwd=os.path.dirname(small))
    assert status == ExitStatus.FAILED, lines
    (finding,) = json.loads(out)["results"]
    baseline = tmp_path / "baseline.json"
    baseline.write_text(out)
    config = tmp_path / "meshcheck.toml"
    config.write_text(f'[[ignore]]\nid = "{finding["id"]}"\nreason = "reviewed: 0.01 m"\n')
    cwd = os.path.dirname(small)
    status, _, lines = run(["asm.gltf", "--config", config], cwd=cwd)
    assert status == ExitStatus.OK, lines  # the approval holds while nothing moved

    cwd = os.path.dirname(big)
    status, out, lines = run(["asm.gltf", "--format", "json"], cwd=cwd)
    (moved,) = json.loads(out)["results"]
    assert (moved["a"], moved["b"]) == (finding["a"], finding["b"])
    assert moved["id"] != finding["id"]
    status, _, lines = run(["asm.gltf", "--config", config], cwd=cwd)
    assert status == ExitStatus.FAILED, lines  # the approval lapsed
    status, _, lines = run(
        ["asm.gltf", "--baseline", baseline, "--fail-on", "new", "--no-config"], cwd=cwd
    )
    assert status == ExitStatus.FAILED, lines  # new against the baseline


# ------------------------------------------------------------------------------------------
# The scheduler: addresses checked up front, every wait on it bounded

PLATE = os.path.join(os.path.dirname(__file__), "..", "sample_meshes", "plate.stl")


@pytest.mark.posix_only
@pytest.mark.parametrize(
    "address", ["foo://bar:1", "inproc://x", "ucx://10.0.0.5:8786", "tcp://[::1", "tcp://h:99999"]
)
def test_scheduler_address_is_checked_before_any_work(address):
    # 0.2: exit 4 after ~23 s with Client.__del__ tracebacks
    start = time.monotonic()
    status, _, lines = run(["--no-config", "--scheduler", address, PLATE], seconds=120)
    one_error(lines, status, ExitStatus.USAGE, "scheduler")
    assert len(lines) == 1, lines
    assert time.monotonic() - start < 60  # interpreter start-up on a loaded machine


class Listener:
    """A TCP server on 127.0.0.1 in a child process, stopped by its process id.

    ``mode`` ``silent`` accepts and never answers; ``garbage`` sends bytes that are no Dask
    message; ``huge`` sends a frame header announcing 2^62 bytes.
    """

    CODE = """
import socket, sys, time
mode = sys.argv[1]
server = socket.socket()
server.bind(("127.0.0.1", 0))
server.listen(16)
print(server.getsockname()[1], flush=True)
held = []
while True:
    conn, _ = server.accept()
    held.append(conn)
    if mode == "garbage":
        conn.sendall(b"HTTP/1.0 200 OK\\r\\n\\r\\n" + bytes(range(256)) * 64)
    elif mode == "huge":
        conn.sendall((1).to_bytes(8, "little") + (1 << 62).to_bytes(8, "little"))
"""

    def __init__(self, mode: str):
        self.process = subprocess.Popen(
            [sys.executable, "-c", self.CODE, mode], stdout=subprocess.PIPE, text=True
        )
        self.port = int(self.process.stdout.readline())

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        os.kill(self.process.pid, 9)
        self.process.wait(timeout=30)


@pytest.mark.posix_only
@pytest.mark.parametrize("mode", ["silent", "garbage", "huge"])
def test_scheduler_that_never_answers_is_exit_3_within_seconds(mode):
    pytest.importorskip("distributed")
    with Listener(mode) as server:
        address = f"tcp://127.0.0.1:{server.port}"
        start = time.monotonic()
        status, _, lines = run(["--no-config", "--scheduler", address, PLATE], seconds=150)
        seconds = time.monotonic() - start
    one_error(lines, status, ExitStatus.INPUT, address, "scheduler")
    assert not any("Exception ignored" in line for line in lines), lines
    assert seconds < 60, seconds  # 0.2: still running after 300 s


# ------------------------------------------------------------------------------------------
# The configuration file: read without blocking, bounded in size and nesting


def _config_cases(folder):
    fifo = folder / "fifo.toml"
    os.mkfifo(fifo)
    deep = folder / "deep.toml"
    deep.write_text("x = " + "[" * 50_000 + "]" * 50_000 + "\n")
    sparse = folder / "sparse.toml"
    with open(sparse, "wb") as fh:
        fh.truncate(3 << 30)  # 3 GB of holes: no disk used
    return {"fifo": fifo, "/dev/zero": "/dev/zero", "nested": deep, "sparse": sparse}


@pytest.mark.posix_only
@pytest.mark.parametrize("case", ["fifo", "/dev/zero", "nested", "sparse"])
def test_config_that_is_a_fifo_a_device_deep_or_huge_is_one_line(tmp_path, case):
    # 0.2: a FIFO hung, /dev/zero ate 1.8 GB, 50,000-deep TOML was a RecursionError (exit 4),
    # a 3 GB sparse file a MemoryError
    config = _config_cases(tmp_path)[case]
    start = time.monotonic()
    status, _, lines = run(["--config", config, PLATE], seconds=120, memory=2 << 30)
    one_error(lines, status, ExitStatus.USAGE, str(config))
    assert len(lines) == 1, lines
    assert time.monotonic() - start < 60


@pytest.mark.posix_only
def test_foreign_pyproject_nested_deep_is_skipped_by_discovery(tmp_path):
    # 0.2: a deeply nested pyproject.toml found by discovery was a RecursionError (exit 4)
    (tmp_path / "pyproject.toml").write_text("x = " + "[" * 50_000 + "]" * 50_000 + "\n")
    status, _, lines = run([os.path.abspath(PLATE)], cwd=tmp_path, seconds=120)
    assert status == ExitStatus.OK, lines


# ------------------------------------------------------------------------------------------
# Wrong PASS 3: an output that is also an input is refused, by path and by inode


def _clash_stl(folder):
    """Two unit cubes overlapping by 0.5 (an interference), as binary STL files."""
    a, b = folder / "a.stl", folder / "b.stl"
    box().export(str(a))
    box(at=(0.5, 0, 0)).export(str(b))
    return a, b


@pytest.mark.posix_only
@pytest.mark.parametrize(
    "case",
    ["baseline-path", "baseline-hardlink", "config", "config-found", "mesh-in-dir", "mesh-link"],
)
def test_output_that_is_an_input_is_refused(tmp_path, case):
    # 0.2: --baseline out/b.json -o out/b.json wrote the failing run's finding into the baseline,
    # and the re-run of the same job was green
    a, b = _clash_stl(tmp_path)
    baseline = tmp_path / "b.json"
    status, out, lines = run([a, b, "--format", "json", "--no-config"])
    baseline.write_text(json.dumps({**json.loads(out), "results": []}))
    config = tmp_path / "meshcheck.toml"
    config.write_text("tolerance = 0.001\n")
    args = {
        "baseline-path": ["--no-config", "--baseline", baseline, "-o", baseline],
        "baseline-hardlink": ["--no-config", "--baseline", baseline, "-o", tmp_path / "hard.json"],
        "config": ["--config", config, "--report", f"json:{config}"],
        "config-found": ["--report", f"json:{config}"],
        "mesh-in-dir": ["--no-config", "-o", tmp_path / "b.stl"],
        "mesh-link": ["--no-config", "-o", tmp_path / "hard.stl"],
    }[case]
    os.link(baseline, tmp_path / "hard.json")
    os.link(b, tmp_path / "hard.stl")
    before = baseline.read_bytes(), config.read_bytes(), b.read_bytes()
    files = [tmp_path] if case == "mesh-in-dir" else [a, b]
    if case == "mesh-in-dir":
        os.unlink(tmp_path / "hard.stl")
    status, _, lines = run([*files, *args, "--fail-on", "new"], cwd=tmp_path)
    one_error(lines, status, ExitStatus.USAGE, "is an input")
    assert (baseline.read_bytes(), config.read_bytes(), b.read_bytes()) == before


# ------------------------------------------------------------------------------------------
# stderr: progress lines carry a prefix, an error is the last line, no PASS after it

SLOW_START = """
import importlib.abc, sys, time

class Slow(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == "meshcheck.pipeline":
            time.sleep(3.0)  # longer than progress.QUIET_SECONDS: the start gets its lines
        return None

sys.meta_path.insert(0, Slow())
"""


@pytest.fixture
def slow_start(tmp_path):
    """Environment whose interpreter takes 3 s to import the pipeline (a busy machine)."""
    folder = tmp_path / "slow"
    folder.mkdir()
    (folder / "sitecustomize.py").write_text(SLOW_START)
    return {"PYTHONPATH": f"{folder}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}


@pytest.mark.linux_only
def test_under_a_slow_start_progress_is_prefixed_and_the_error_is_last(tmp_path, slow_start):
    a, b = _clash_stl(tmp_path)
    status, _, lines = run([a, b, "--no-config", "-o", "/dev/full"], env=slow_start)
    assert any(line.startswith("meshcheck: starting") for line in lines), lines  # it was slow
    one_error(lines, status, ExitStatus.OUTPUT, "/dev/full", "cannot write the report")
    assert all(line.startswith(("meshcheck: ", "error: ")) for line in lines), lines


@pytest.mark.linux_only
def test_no_pass_line_follows_an_output_error(tmp_path):
    # 0.2: "error: out/full: cannot write the report" then "PASS: ...; report written to ..."
    a, b = box(), box(at=(3, 0, 0))
    paths = [tmp_path / "a.stl", tmp_path / "b.stl"]
    for mesh, path in zip((a, b), paths, strict=True):
        mesh.export(str(path))
    report = tmp_path / "r.json"
    status, _, lines = run(
        [*paths, "--no-config", "--format", "json", "-o", report, "--report", "json:/dev/full"]
    )
    one_error(lines, status, ExitStatus.OUTPUT, "/dev/full")
    assert not any("PASS" in line for line in lines), lines
    assert json.loads(report.read_text())["summary"]["passed"] is True  # the other one is out


# ------------------------------------------------------------------------------------------
# Wrong PASS 4: the float32 floor applies only to coordinates that went through float32


def _ascii_stl(path, mesh) -> str:
    """An ASCII STL in full float64 (repr of every coordinate)."""
    lines = ["solid part"]
    for tri in mesh.triangles.tolist():
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {x!r} {y!r} {z!r}" for x, y, z in tri]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid part", ""]))
    return str(path)


@pytest.mark.posix_only
def test_part_buried_far_from_the_origin_in_ascii_stl_is_interference(tmp_path):
    # 0.2: a 0.01 mm part inside a 1000 mm part at 1e6 mm, both ASCII STL in float64: the float32
    # floor (~0.95 mm there) made the pair touching, exit 0
    at = (1e6 + 0.123456789, 2.5, 0.0)
    big = _ascii_stl(tmp_path / "big.stl", box((1000.0, 1000.0, 1000.0), at))
    small = _ascii_stl(tmp_path / "small.stl", box((0.01, 0.01, 0.01), at))
    status, out, lines = run([big, small, "--no-config", "--format", "json"])
    assert status == ExitStatus.FAILED, lines
    (finding,) = json.loads(out)["results"]
    assert finding["status"] == "interference"
    assert finding["tolerance"] < 1e-6


@pytest.mark.parametrize(
    ("name", "expected"),
    [("binary.stl", True), ("ascii.stl", False), ("part.obj", False), ("part.glb", True),
     ("float.ply", True), ("double.ply", False), ("part.3mf", False), ("part.step", False)],
)  # fmt: skip
def test_each_reader_says_whether_its_coordinates_went_through_float32(tmp_path, name, expected):
    from meshcheck.load import load_bodies

    mesh, path = box(), tmp_path / name
    if name == "ascii.stl":
        _ascii_stl(path, mesh)
    elif name == "part.3mf":
        write_3mf(path, '<item objectid="1"/>')
    elif name == "part.step":  # OpenCASCADE meshes and places in double
        products = {"a": step_writer.box((0, 0, 0), (1, 1, 1))}
        step_writer.write_step(str(path), products, [("a", np.eye(4))])
    elif name.endswith(".ply"):
        kind = "float" if name == "float.ply" else "double"
        head = f"ply\nformat ascii 1.0\nelement vertex {len(mesh.vertices)}\n"
        head += "".join(f"property {kind} {c}\n" for c in "xyz")
        head += f"element face {len(mesh.faces)}\nproperty list uchar int vertex_indices\n"
        rows = [" ".join(map(repr, v)) for v in mesh.vertices.tolist()]
        rows += ["3 " + " ".join(map(str, f)) for f in mesh.faces.tolist()]
        path.write_text(head + "end_header\n" + "\n".join(rows) + "\n")
    else:
        mesh.export(str(path))
    (body,) = load_bodies([str(path)])
    assert body.is_float32 is expected


# ------------------------------------------------------------------------------------------
# The cache: entries that are FIFOs are misses; folders that are symbolic links are not followed


def _cached_run(tmp_path, files, cache):
    # CoACD runs on these small parts only when forced (the cost model says it never pays here),
    # so that there are decomposition entries to plant FIFOs and links in.
    args = [*files, "--no-config", "--cache-dir", cache, "-j", "1"]
    return run(args, cache=True, seconds=120, env={"MESHCHECK_COACD_BUDGET": "300"})


def _entries(cache):
    return [
        os.path.join(folder, name)
        for folder, _, names in os.walk(cache)
        for name in names
        if not name.startswith(".") and name.endswith((".bin", ".json", ".npz"))
    ]


@pytest.mark.posix_only
def test_cache_entries_that_are_fifos_are_misses(tmp_path):
    # 0.2: a FIFO in place of a decomposition, pair or tessellation entry hung every run
    files = list(_clash_stl(tmp_path))
    step = tmp_path / "pair.step"
    products = {
        "a": step_writer.box((0, 0, 0), (1, 1, 1)),
        "b": step_writer.box((0, 0, 0), (1, 1, 1)),
    }
    moved = np.eye(4)
    moved[0, 3] = 0.5
    step_writer.write_step(str(step), products, [("a", np.eye(4)), ("b", moved)])
    files.append(step)
    cache = tmp_path / "cache"
    status, _, lines = _cached_run(tmp_path, files, cache)
    assert status == ExitStatus.FAILED, lines
    entries = _entries(cache)
    kinds = {os.path.basename(os.path.dirname(os.path.dirname(e))).split("-v")[0] for e in entries}
    assert {"decompositions", "pairs", "tessellations"} <= kinds, entries
    for entry in entries:
        os.unlink(entry)
        os.mkfifo(entry)
    status, _, lines = _cached_run(tmp_path, files, cache)  # 0.2: TimeoutExpired
    assert status == ExitStatus.FAILED, lines


@pytest.mark.posix_only
def test_cache_subfolder_symlinks_are_never_followed(tmp_path):
    # 0.2: decompositions-vN/XX -> elsewhere: entries were written outside the cache, and the
    # stale-file clean-up deleted .tmp-* files there
    files = list(_clash_stl(tmp_path))
    cache = tmp_path / "cache"
    status, _, lines = _cached_run(tmp_path, files, cache)
    assert status == ExitStatus.FAILED, lines
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    bait = elsewhere / ".tmp-precious"
    bait.write_text("not the cache's")
    os.utime(bait, (0, 0))  # older than any stale cutoff
    for entry in _entries(cache):
        folder = os.path.dirname(entry)
        if not os.path.islink(folder):
            for name in os.listdir(folder):
                os.unlink(os.path.join(folder, name))
            os.rmdir(folder)
            os.symlink(elsewhere, folder)
    status, _, lines = _cached_run(tmp_path, files, cache)
    assert status == ExitStatus.FAILED, lines
    assert os.listdir(elsewhere) == [".tmp-precious"], os.listdir(elsewhere)


# ------------------------------------------------------------------------------------------
# Candidate pairs are budgeted like triangles


@pytest.mark.posix_only
def test_2000_coincident_cubes_are_one_duplicate_finding(tmp_path):
    # 0.2: 2 million candidate pairs, 5,872 done after 60 s at 1.3 GB. Copies at one spot are
    # one duplicate finding, decided before any pair is verified.
    items = '<item objectid="1"/>' * 2000
    path = write_3mf(tmp_path / "stack.3mf", items)
    start = time.monotonic()
    status, out, lines = run([path, "-j", "1", "--format", "json"], seconds=180, memory=3 << 30)
    assert status == ExitStatus.FAILED, lines
    (finding,) = json.loads(out)["results"]
    assert finding["status"] == "duplicate" and len(finding["members"]) == 2000
    assert time.monotonic() - start < 120


@pytest.mark.posix_only
def test_overlapping_cubes_past_the_pair_budget_are_refused_with_the_count(tmp_path):
    # Not duplicates (each 0.0005 further along x, 30 times the tolerance), all overlapping the
    # unit cube:
    # 1,001 parts make 500,500 candidate pairs, over the budget of 500,000.
    items = "".join(
        f'<item objectid="1" transform="1 0 0 0 1 0 0 0 1 {0.0005 * k!r} 0 0"/>'
        for k in range(1001)
    )
    path = write_3mf(tmp_path / "fan.3mf", items)
    start = time.monotonic()
    status, _, lines = run([path, "-j", "1"], seconds=180, memory=3 << 30)
    one_error(lines, status, ExitStatus.INPUT, "500_500 candidate part pairs", "1001 parts")
    assert time.monotonic() - start < 120


@pytest.mark.posix_only
def test_2000_coincident_step_instances_are_one_duplicate_not_a_memory_error(tmp_path):
    # 0.2: MemoryError in surfaces_near, exit 4
    path = tmp_path / "stack.step"
    products = {"cube": step_writer.box((0, 0, 0), (1, 1, 1))}
    step_writer.write_step(str(path), products, [("cube", np.eye(4))] * 2000)
    status, out, lines = run([path, "-j", "1", "--format", "json"], seconds=300, memory=3 << 30)
    assert status == ExitStatus.FAILED, lines
    (finding,) = json.loads(out)["results"]
    assert finding["status"] == "duplicate" and len(finding["members"]) == 2000


# ------------------------------------------------------------------------------------------
# Budgets are checked before reading

#: Address space for the 500 MB cases: a run needs ~1.2 GiB of it (mostly mapped libraries), so
#: holding the file and parsing it cannot fit, while refusing it before reading does.
SMALL_MEMORY = 1400 << 20


@pytest.mark.posix_only
def test_500_mb_obj_line_is_refused_as_it_is_read(tmp_path):
    # 0.2: exit 3 only after 15 s and 1.7 GB, reason "MemoryError"
    path = tmp_path / "line.obj"
    with open(path, "wb") as fh:
        fh.write(b"v 0 0 0 ")
        fh.truncate(500 << 20)  # sparse: one 500 MB line, no disk used
    start = time.monotonic()
    status, _, lines = run([path], seconds=120, memory=SMALL_MEMORY)
    one_error(lines, status, ExitStatus.INPUT, str(path), "line over 1_048_576 bytes")
    assert time.monotonic() - start < 60


@pytest.mark.posix_only
def test_stl_declaring_more_triangles_than_allowed_is_refused_before_reading(tmp_path):
    # 0.2: a 500 MB STL declaring 10^7 triangles was refused only after 1.2 GB; here 1 GB, so
    # reading it cannot fit the address space
    path = tmp_path / "big.stl"
    count = 20_000_000
    with open(path, "wb") as fh:
        fh.write(b"\0" * 80 + count.to_bytes(4, "little"))
        fh.truncate(84 + 50 * count)  # sparse, and the size a binary STL of that count has
    status, _, lines = run([path, "--max-triangles", "1000000"], seconds=120, memory=SMALL_MEMORY)
    one_error(lines, status, ExitStatus.INPUT, str(path), "20_000_000 triangles", "--max-triangles")


# ------------------------------------------------------------------------------------------
# Names that would be runner commands or mentions


@pytest.mark.posix_only
@pytest.mark.parametrize("fmt", ["text", "github"])
def test_runner_command_syntax_in_a_name_is_escaped(tmp_path, fmt):
    # 0.2: "##[error]FORGED" passed raw into the text and GitHub reports
    a, b = tmp_path / "##[error]FORGED.stl", tmp_path / "##vso[task.complete]x.stl"
    box().export(str(a))
    box(at=(0.5, 0, 0)).export(str(b))
    status, out, lines = run([a, b, "--no-config", "--format", fmt])
    assert status == ExitStatus.FAILED, lines
    assert "FORGED" in out
    assert "##[" not in out and "##vso[" not in out, out
    assert not any("##[" in line for line in lines), lines


@pytest.mark.posix_only
def test_mention_in_a_name_is_escaped_in_markdown(tmp_path):
    # 0.2: "@user" in a part name pinged the user when the summary was posted on a PR
    a, b = tmp_path / "@octocat.stl", tmp_path / "b.stl"
    box().export(str(a))
    box(at=(0.5, 0, 0)).export(str(b))
    status, out, lines = run([a, b, "--no-config", "--format", "markdown"])
    assert status == ExitStatus.FAILED, lines
    assert "octocat" in out
    assert "@octocat" not in out, out


# ------------------------------------------------------------------------------------------
# Workers


def test_jobs_are_capped_by_cores():
    # 0.2: -j 10000 with 40 parts started 40 workers on 2 cores (2.6 GB)
    from meshcheck.execute import default_jobs, executor_for

    with executor_for(jobs=10_000) as executor:
        assert 1 <= executor.jobs <= default_jobs()
        assert not executor.is_started  # nothing was started to find out


@pytest.mark.linux_only
def test_jobs_are_capped_by_available_memory():
    from meshcheck.execute import WORKER_BYTES, executor_for

    (available,) = [ln for ln in open("/proc/meminfo") if ln.startswith("MemAvailable:")]
    with executor_for(jobs=10_000) as executor:
        assert executor.jobs <= max(1, int(available.split()[1]) * 1024 // WORKER_BYTES)
        assert not executor.is_started


# ------------------------------------------------------------------------------------------
# Sweeps are budgeted in work, like every other input


@pytest.mark.posix_only
@pytest.mark.parametrize("joint", ["revolute", "fixed"])
def test_sweep_of_a_3000_link_chain_stops_at_its_budget_with_progress(tmp_path, joint):
    # 4,498,500 link pairs: those the budget cannot pay for are undecided, counted, not listed,
    # never "never". Joined by fixed joints, each pair is one check on the real meshes and
    # costs the least a pair costs (4,096): the budget bounds how many are visited.
    from meshes import chain_urdf

    path = tmp_path / "chain.urdf"
    path.write_text(chain_urdf(3000).replace('type="revolute"', f'type="{joint}"'))
    # A budget of 10 million: several seconds of sweeping, so progress lines are due.
    args = [path, "--sweep", "--sweep-budget", "10000000", "-j", "1", "--format", "json"]
    status, out, lines = run(args, seconds=60)
    assert status == ExitStatus.OK, lines  # a URDF robot's sweep never fails the run
    (sweep,) = json.loads(out)["sweeps"]
    assert json.loads(out)["summary"]["sweep_budget"] == 10_000_000
    assert sweep["budget"] == 10_000_000 and 10_000_000 <= sweep["work"] < 10_100_000
    assert sweep["unswept"] > 4_000_000 and len(sweep["pairs"]) <= 10_000_000 // 4096 + 1
    assert sweep["counts"]["undecided"] >= sweep["unswept"]
    assert sum(sweep["counts"].values()) == 3000 * 2999 // 2
    assert any("sweeping link pairs" in line for line in lines), lines
    assert any("the sweep budget (10,000,000) ran out" in line for line in lines), lines
