"""A STEP file read ahead in a worker (``load.step.ahead``) gives the run exactly what reading it
in this process gives: the same products, meshes and exact solids; and whenever the worker's read
does not fit (other bytes, a file it cannot read, a tessellation in the cache) the file is read
here, as without it."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from meshcheck.cache import TessellationCache
from meshcheck.errors import InputError
from meshcheck.execute import LocalPool, Task, _has_pidfds, has_early, stop_early
from meshcheck.load.step import ahead, read, read_step, tessellate
from meshcheck.load.step.tessellate import PREPARE
from meshcheck.settings import Settings

HERE = os.path.dirname(os.path.abspath(__file__))
BOX_SIDES = os.path.join(HERE, "data", "step", "box_sides.STEP")
SAMPLE = os.path.join(HERE, "..", "sample_meshes", "assembly.step")


@pytest.fixture(autouse=True)
def _two_processes(monkeypatch):
    """A run with a second local process, on any machine; no worker outlives its test."""
    monkeypatch.setattr(ahead, "local_jobs", lambda jobs: 2)
    yield
    stop_early()


def _settings(**options) -> Settings:
    return Settings.from_options(config=None, jobs=2, **options)


def _same_assembly(one, two) -> None:
    assert one.unit == two.unit and one.deflection == two.deflection
    assert [n for n, _, _ in one.items] == [n for n, _, _ in two.items]
    for (_, a, pa), (_, b, pb) in zip(one.items, two.items, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
        assert np.array_equal(pa, pb) and a.metadata == b.metadata
    for name, _, _ in one.items:  # the exact solids: the same BRep text
        assert one.solids.product_text(name) == two.solids.product_text(name)


def test_a_file_read_ahead_is_the_file_read_here_and_its_worker_joins_the_pool(monkeypatch):
    """The worker that read the file ahead joins the run's pool, and the twin it forked (a
    small file: its pairs are the workers' alone) the pool's reserve."""
    here = read_step(BOX_SIDES)
    ahead.start([BOX_SIDES], _settings())
    assert has_early(ahead._key(BOX_SIDES))

    def not_here(*args):
        raise AssertionError("the file was read in this process")

    monkeypatch.setattr(read, "read_document", not_here)
    monkeypatch.setattr(tessellate, "mesh_task", not_here)  # the worker meshed it: welded here
    with LocalPool(2) as pool:
        there = read_step(BOX_SIDES, executor=pool)
        assert (len(pool.workers), pool.prepared) == (1, {PREPARE})
        worker = pool.workers[0].process.pid
        task = Task((0.0,))
        assert pool.map("meshcheck.execute:sleep_then_pid", [task]) == [worker]
        # its twin, forked with OpenCASCADE loaded, waits for the pairs this process leaves
        # (where there are pidfds: a twin is killed through one)
        twins = 1 if _has_pidfds() else 0
        assert [w.prepare for w in pool.reserve] == [PREPARE] * twins
    assert not has_early(ahead._key(BOX_SIDES))
    _same_assembly(here, there)


def test_a_large_files_twin_imports_the_welding_while_the_worker_reads_and_serves(monkeypatch):
    """A large file's products are meshed here and in one worker, which welds them with
    trimesh: the twin imports it while the worker reads, and takes the worker's place in the
    pool (the worker waits in reserve). The meshes are the same."""
    here = read_step(BOX_SIDES)
    for module in (ahead, read):
        monkeypatch.setattr(module, "PREPARE_BYTES", 1)  # every file is large
    ahead.start([BOX_SIDES], _settings())
    with LocalPool(2) as pool:
        there = read_step(BOX_SIDES, executor=pool)
        if _has_pidfds():  # a twin only where it can be killed through a pidfd
            (serving,) = pool.workers
            assert serving.is_twin and serving.more_prepared
            assert [w.is_twin for w in pool.reserve] == [False]
            asked = [Task(("trimesh",))]
            assert pool.map("meshcheck.execute:is_imported", asked, grow=False) == [True]
            assert not serving.preparing  # its reply to the imports was read first
    _same_assembly(here, there)


def test_other_bytes_than_the_worker_read_are_read_here():
    with open(SAMPLE, "rb") as f:
        other = f.read()
    ahead.start([BOX_SIDES], _settings())
    with LocalPool(2) as pool:  # the load stage read other bytes at that path
        there = read_step(BOX_SIDES, data=other, executor=pool)
    _same_assembly(read_step(BOX_SIDES, data=other), there)


def test_other_settings_than_the_worker_had_are_read_here():
    ahead.start([BOX_SIDES], _settings())  # the default deflection
    with LocalPool(2) as pool:
        there = read_step(BOX_SIDES, deflection=0.05, deflection_unit="mm", executor=pool)
    _same_assembly(read_step(BOX_SIDES, deflection=0.05, deflection_unit="mm"), there)


def test_the_settings_the_command_line_gives_are_the_ones_read_step_is_given(monkeypatch):
    """A file given a unit and a deflection on the command line is still read ahead."""
    settings = _settings(step_deflection=0.001, units="in", file_units={BOX_SIDES: "mm"})
    ahead.start([BOX_SIDES], settings)

    def not_here(*args):
        raise AssertionError("the file was read in this process")

    monkeypatch.setattr(read, "read_document", not_here)
    with LocalPool(2) as pool:
        read_step(BOX_SIDES, deflection=0.001, deflection_unit="in", unit="mm", executor=pool)


def test_a_file_the_worker_cannot_read_is_refused_as_it_is_here(tmp_path):
    bad = tmp_path / "bad.step"
    bad.write_bytes(b"ISO-10303-21;\nHEADER;\nthis is not STEP\n")
    with pytest.raises(InputError) as expected:
        read_step(str(bad))
    ahead.start([str(bad)], _settings())
    with LocalPool(2) as pool, pytest.raises(InputError) as refused:
        read_step(str(bad), executor=pool)
    assert str(refused.value) == str(expected.value)


def test_a_tessellation_in_the_cache_stops_the_worker(tmp_path):
    cache = TessellationCache(str(tmp_path), secret=b"k" * 32)
    here = read_step(BOX_SIDES, cache=cache)
    ahead.start([BOX_SIDES], _settings())
    key = ahead._key(BOX_SIDES)
    from meshcheck.execute import _EARLY

    process = _EARLY[key].process
    with LocalPool(2) as pool:
        cached = read_step(BOX_SIDES, cache=cache, executor=pool)
        assert pool.workers == []
    assert not has_early(key) and process.poll() is not None  # killed, not left reading
    _same_assembly(here, cached)


def test_the_later_step_files_are_read_in_the_pool_as_they_are_read_here(monkeypatch, tmp_path):
    """The first STEP file is read ahead; the others are read by the pool once the first of
    them is reached, and give the arrays reading them here gives; a file the pool cannot read
    is refused here, as without the pool."""
    from test_load_parallel import assert_same

    from meshcheck.load.files import StepOptions, read_files
    from meshcheck.load.limits import Budget, Limits

    copy = tmp_path / "box_sides_copy.stp"
    copy.write_bytes(open(BOX_SIDES, "rb").read())
    paths, options = [BOX_SIDES, SAMPLE, str(copy)], StepOptions(None, None)
    here = read_files(paths, Budget(Limits()), options)
    ahead.start(paths, _settings())

    def not_here(*args):
        raise AssertionError("a STEP file was read by the load stage in this process")

    monkeypatch.setattr(read, "read_document", not_here)
    with LocalPool(2) as pool:
        there = read_files(paths, Budget(Limits()), options, executor=pool)
    assert_same(here, there)
    assert ahead._READ == {}  # every file read in the pool was taken

    bad = tmp_path / "bad.step"
    bad.write_bytes(b"ISO-10303-21;\nHEADER;\nthis is not STEP\n")
    monkeypatch.undo()
    with pytest.raises(InputError) as expected:
        read_files([BOX_SIDES, str(bad)], Budget(Limits()), options)
    with LocalPool(2) as pool, pytest.raises(InputError) as refused:
        read_files([BOX_SIDES, str(bad)], Budget(Limits()), options, executor=pool)
    assert str(refused.value) == str(expected.value)


def test_a_later_step_file_cached_past_the_bytes_or_with_no_worker_is_not_read_in_the_pool(
    tmp_path, monkeypatch
):
    cache = TessellationCache(str(tmp_path / "cache"), secret=b"k" * 32)
    read_step(SAMPLE, cache=cache)
    copy = tmp_path / "box_sides_copy.stp"
    copy.write_bytes(open(BOX_SIDES, "rb").read())
    paths, defaults = [SAMPLE, str(copy)], [(None, None, None)] * 2
    with LocalPool(2) as pool:
        ahead.read_in_pool(paths, defaults, 10**6, pool, cache)
        assert ahead._READ == {}  # no worker to read them: a fresh one imports OpenCASCADE first
        pool.map("meshcheck.execute:sleep_then_pid", [Task((0.0,))])  # one started
        ahead.read_in_pool(paths, defaults, 10**6, pool, cache)
        assert set(ahead._READ) == {os.path.realpath(copy)}
        ahead.stop()  # the run is over: what was not taken is forgotten
        assert ahead._READ == {}
        monkeypatch.setattr(ahead, "POOL_READ_BYTES", os.path.getsize(copy) - 1)
        ahead.read_in_pool(paths, defaults, 10**6, pool, cache)  # past the bytes read at once
        assert ahead._READ == {}


def test_nothing_is_read_ahead_for_one_process_a_cluster_or_no_step_file(monkeypatch, tmp_path):
    key = ahead._key(BOX_SIDES)
    monkeypatch.setattr(ahead, "local_jobs", lambda jobs: 1)
    ahead.start([BOX_SIDES], _settings())
    assert not has_early(key)
    monkeypatch.setattr(ahead, "local_jobs", lambda jobs: 2)
    ahead.start([BOX_SIDES], _settings(scheduler="tcp://127.0.0.1:1"))
    assert not has_early(key)
    (tmp_path / "in_a_folder.step").write_bytes(open(BOX_SIDES, "rb").read())
    plate = os.path.join(HERE, "..", "sample_meshes", "plate.stl")
    ahead.start([str(tmp_path), plate], _settings())  # a folder's files are not looked for
    assert not has_early(ahead._key(str(tmp_path / "in_a_folder.step")))


def test_the_command_reports_the_same_bytes_with_and_without_reading_ahead(tmp_path):
    reports = []
    for jobs in ("1", "2"):
        command = [sys.executable, "-m", "meshcheck", BOX_SIDES, SAMPLE, "-j", jobs]
        command += ["--format", "json", "--no-cache"]
        done = subprocess.run(command, capture_output=True, cwd=tmp_path, timeout=300)
        assert done.returncode == 1, done.stderr.decode()[-2000:]
        reports.append(done.stdout)
    assert reports[0] == reports[1]
    assert json.loads(reports[0])["summary"]["interference"] > 0


@pytest.mark.parametrize("files", [[BOX_SIDES], [BOX_SIDES, SAMPLE]])
def test_a_small_file_read_ahead_is_decided_by_its_worker_without_opencascade_here(tmp_path, files):
    """The worker that read a small file ahead triangulates it and decides its pairs on the
    B-rep (a later file is read in the pool); the command's process never loads OpenCASCADE,
    and its report is the one-process report, byte for byte."""
    script = (
        "import sys\n"
        "from meshcheck import cli\n"
        "try:\n"
        "    cli.main(sys.argv[1:], standalone_mode=False)\n"
        "finally:\n"
        "    print('OpenCASCADE here:', 'OCP.OCP' in sys.modules, file=sys.stderr)\n"
    )
    reports = []
    for jobs in ("1", "2"):
        out = tmp_path / f"j{jobs}.json"
        command = [sys.executable, "-c", script, *files, "-j", jobs, "--no-cache"]
        command += ["--format", "json", "-o", str(out)]
        done = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=300)
        assert f"OpenCASCADE here: {jobs == '1'}" in done.stderr, done.stderr[-2000:]
        reports.append(out.read_bytes())
    assert reports[0] == reports[1]
    assert json.loads(reports[0])["summary"]["interference"] > 0


def test_the_command_reads_its_first_step_file_ahead(monkeypatch, tmp_path):
    from meshcheck import cli

    def not_here(*args):
        raise AssertionError("the file was read in this process")

    monkeypatch.setattr(read, "read_document", not_here)
    out = tmp_path / "report.json"
    args = [BOX_SIDES, "-j", "2", "--no-cache", "--format", "json", "-o", str(out)]
    with pytest.raises(SystemExit) as done:
        cli.main(args, standalone_mode=True)
    assert done.value.code == 1
    assert json.loads(out.read_text())["summary"]["interference"] > 0


@pytest.mark.parametrize(
    ("arguments", "reads"),
    [
        ([BOX_SIDES], True),
        ([BOX_SIDES, "-j", "2"], True),
        ([BOX_SIDES, "--jobs=2", "--format", "json"], True),
        (["--", BOX_SIDES], True),
        ([BOX_SIDES, "-j", "1"], False),
        ([BOX_SIDES, "-j1"], False),
        ([BOX_SIDES, "--jobs=1"], False),
        ([BOX_SIDES, "-j", "many"], False),  # a usage error
        ([BOX_SIDES, "--scheduler", "tcp://127.0.0.1:1"], False),
        ([BOX_SIDES, "--help"], False),
        ([BOX_SIDES, "--version"], False),
        ([os.path.join(HERE, "missing.step")], False),
        ([os.path.join(HERE, "..", "sample_meshes", "plate.stl")], False),
        ([], False),
    ],
)
def test_the_command_guesses_from_its_arguments_whether_it_reads_a_step_file_ahead(
    monkeypatch, arguments, reads
):
    from meshcheck import __main__, execute

    monkeypatch.setattr(execute, "local_jobs", lambda jobs: min(jobs or 2, 2))
    monkeypatch.delenv("MESHCHECK_SCHEDULER", raising=False)
    assert __main__.reads_step_ahead(arguments) is reads
    monkeypatch.setenv("MESHCHECK_SCHEDULER", "tcp://127.0.0.1:1")
    assert __main__.reads_step_ahead(arguments) is False


def _command(monkeypatch, arguments: list[str], started: list | None = None) -> tuple[int, list]:
    """``meshcheck ARGUMENTS`` run by the command's entry point in this process: its exit
    status, and the workers it started to import OpenCASCADE (appended to ``started`` as they
    start)."""
    from meshcheck import __main__, execute

    monkeypatch.setattr(execute, "local_jobs", lambda jobs: min(jobs or 2, 2))
    monkeypatch.delenv("MESHCHECK_SCHEDULER", raising=False)
    monkeypatch.setattr(sys, "argv", ["meshcheck", *arguments])
    started = [] if started is None else started
    original = execute._Worker.__init__

    def recorded(self, prepare=None, **kwargs):
        original(self, prepare, **kwargs)
        if prepare == PREPARE:
            started.append(self.process)

    monkeypatch.setattr(execute._Worker, "__init__", recorded)
    with pytest.raises(SystemExit) as done:
        __main__.main()
    return done.value.code, started


def test_the_command_starts_the_worker_that_reads_ahead_before_it_reads_its_options(
    monkeypatch, tmp_path
):
    """The worker the entry point starts (before the command line's imports) is the one that
    reads the file: no other is started for it, and none is left."""

    def not_here(*args):
        raise AssertionError("the file was read in this process")

    monkeypatch.setattr(read, "read_document", not_here)
    out = tmp_path / "report.json"
    args = [BOX_SIDES, "-j", "2", "--no-cache", "--format", "json", "-o", str(out)]
    status, started = _command(monkeypatch, args)
    assert status == 1 and json.loads(out.read_text())["summary"]["interference"] > 0
    assert len(started) == 1 and started[0].poll() is not None


def test_a_worker_started_for_a_read_the_run_does_not_make_is_stopped(monkeypatch, tmp_path):
    """The guess was wrong (the STEP file named is the report's path, not an input): the worker
    is stopped before the check starts. A usage error stops it too."""
    from meshcheck import pipeline

    report = tmp_path / "old_report.step"
    report.write_text("")
    plate = os.path.join(HERE, "..", "sample_meshes", "plate.stl")
    running_at_check = []
    original = pipeline.check

    def check(*args, **kwargs):
        running_at_check.append(any(p.poll() is None for p in started))
        return original(*args, **kwargs)

    started: list = []
    monkeypatch.setattr(pipeline, "check", check)
    args = [plate, "--no-cache", "--format", "json", "-o", str(report)]
    status, _ = _command(monkeypatch, args, started)
    assert status == 0 and len(started) == 1 and running_at_check == [False]
    assert json.loads(report.read_text())["summary"]["parts"] == 1
    status, workers = _command(monkeypatch, [BOX_SIDES, "--tolerance", "-1"])
    assert status == 2 and len(workers) == 1 and workers[0].poll() is not None


def test_a_ctrl_c_while_the_command_line_is_imported_is_one_line(monkeypatch, capsys):
    """Ctrl-C after the worker started, before the command line's modules are imported (they
    say it themselves from then on): exit 130, one line, the worker stopped."""
    import types

    class Interrupted(types.ModuleType):
        def __getattr__(self, name):
            raise KeyboardInterrupt

    monkeypatch.setitem(sys.modules, "meshcheck.cli", Interrupted("meshcheck.cli"))
    status, started = _command(monkeypatch, [BOX_SIDES, "-j", "2"])
    assert status == 130 and capsys.readouterr().err == "error: interrupted\n"
    assert len(started) == 1 and started[0].poll() is not None
