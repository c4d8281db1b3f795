"""Running on a Dask cluster: real scheduler and worker processes on 127.0.0.1 only.

Each test bounds its own time and stops what it started, by process id.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import sysconfig
import time

import pytest
import trimesh
from click.testing import CliRunner

from meshcheck import pipeline
from meshcheck.cli import main
from meshcheck.execute import DaskExecutor, Task
from meshcheck.reports import render

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SAMPLES = os.path.join(ROOT, "sample_meshes")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def assembly(directory, boxes: int = 12) -> list[str]:
    """The concave bracket on the plate (decomposed on the cluster), and a row of boxes, each
    overlapping the next, so there are pairs to verify: each box a little taller than the one
    before, so each pair is a pair class of its own (``verify.classes``), decided on its own."""
    os.makedirs(directory, exist_ok=True)
    paths = [os.path.join(SAMPLES, "plate.stl"), os.path.join(SAMPLES, "bracket.stl")]
    for k in range(boxes):
        box = trimesh.creation.box(extents=[10, 10, 10 + 0.01 * k])
        box.apply_translation([200.0 + 9.5 * k, 0.0, 0.0])
        path = os.path.join(directory, f"box{k:02d}.stl")
        box.export(path)
        paths.append(path)
    return paths


def local_report(paths, tmp_path) -> str:
    result = pipeline.check(paths, config=None, cache_dir=tmp_path / "local-cache", jobs=1)
    return render(result, "json")


def test_without_a_scheduler_dask_is_never_imported(tmp_path):
    code = (
        "import sys, meshcheck\n"
        f"meshcheck.check([{os.path.join(SAMPLES, 'plate.stl')!r}], cache_dir={str(tmp_path)!r})\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_an_unreachable_scheduler_is_one_line_at_once(tmp_path):
    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{free_port()}"
    started = time.monotonic()
    result = CliRunner().invoke(
        main,
        ["--no-config", "--scheduler", address, os.path.join(SAMPLES, "plate.stl")],
        catch_exceptions=False,
    )
    assert result.exit_code == 3
    assert result.stderr.startswith(f"error: {address}: cannot reach the Dask scheduler")
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert time.monotonic() - started < 30


def test_a_malformed_scheduler_address_is_a_usage_error():
    result = CliRunner().invoke(
        main, ["--no-config", "--scheduler", "tcp://a b", os.path.join(SAMPLES, "plate.stl")]
    )
    assert result.exit_code == 2
    assert result.stderr.startswith("error: scheduler must be a scheduler address")


def loopback_cluster(distributed):
    """Two single-threaded worker processes and their scheduler on 127.0.0.1 (the caller
    closes it)."""
    return distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        env={"OMP_NUM_THREADS": "1"},
    )


@pytest.mark.slow
def test_a_local_cluster_gives_the_local_report(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")
    # A couple of parts never repay CoACD, and open ones never go (decompose.coacd_budgets):
    # force it, so there are decompositions to cache.
    monkeypatch.setenv("MESHCHECK_COACD_BUDGET", "300")
    paths = assembly(tmp_path / "parts")
    expected = local_report(paths, tmp_path)
    cluster = loopback_cluster(distributed)
    try:
        settings = pipeline.Settings.from_options(
            cache_dir=tmp_path / "cluster-cache", scheduler=cluster.scheduler_address
        )
        result = pipeline.check(paths, settings)
        assert render(result, "json") == expected
        # the client wrote the caches: a second run reuses them and still agrees
        again = pipeline.check(paths, settings)
        assert render(again, "json") == expected
        # tasks from an iterator, which puts the shared values they need as it makes them
        with DaskExecutor(cluster.scheduler_address) as executor:
            shared: dict = {}

            def tasks():
                for key in ("a", "bb"):
                    shared[key] = key * 1000
                    yield Task((key,), needs=(key,))

            assert executor.map("meshcheck.execute:shared_length", tasks(), shared=shared) == [
                1000,
                2000,
            ]
    finally:
        cluster.close(timeout=20)
    entries = [n for _, _, files in os.walk(tmp_path / "cluster-cache") for n in files]
    assert any(n.endswith(".bin") for n in entries) and any(n.endswith(".json") for n in entries)
    assert not any(n.startswith(".tmp-") for n in entries)


@pytest.mark.slow
def test_an_instanced_plant_on_a_cluster_gives_the_local_report(tmp_path):
    distributed = pytest.importorskip("distributed")
    from test_pair_classes import plant_gltf

    path = plant_gltf(tmp_path / "plant.gltf")
    options = {"config": None, "file_units": {path: "mm"}}
    expected = render(pipeline.check([path], cache_dir=None, jobs=1, **options), "json")
    cluster = loopback_cluster(distributed)
    try:
        for _ in range(2):  # cold, then with the verdicts the first run cached, by class
            result = pipeline.check(
                [path], cache_dir=tmp_path / "cache", scheduler=cluster.scheduler_address, **options
            )
            assert render(result, "json") == expected
    finally:
        cluster.close(timeout=20)


class _Processes:
    """Processes started by a test, stopped by pid at the end."""

    def __init__(self):
        self.started: list[subprocess.Popen] = []

    def start(self, args, **kwargs) -> subprocess.Popen:
        process = subprocess.Popen(
            args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **kwargs
        )
        self.started.append(process)
        return process

    def stop(self) -> None:
        for process in self.started:
            if process.poll() is None:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(timeout=30)


def _wait_for_workers(address: str, count: int, timeout: float) -> None:
    from distributed import Client

    with Client(address, timeout=timeout) as client:
        client.wait_for_workers(count, timeout=timeout)


def _busy_worker(address: str, workers, *, deadline: float) -> subprocess.Popen:
    """The worker process that is running a meshcheck task, as soon as one is."""
    from distributed import Client

    with Client(address, timeout=30) as client:
        while time.monotonic() < deadline:
            busy = [w for w, keys in client.processing().items() if keys]
            if busy:
                pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
                return next(w for w in workers if w.pid == pid)
            time.sleep(0.05)
    raise AssertionError("no worker ever ran a task")


@pytest.mark.posix_only
@pytest.mark.slow
def test_dask_scheduler_and_workers_a_worker_killed_mid_run(tmp_path):
    pytest.importorskip("distributed")
    # the dask extra installs the command with the package, beside this Python or in the
    # scripts folder of its install scheme
    folders = [os.path.dirname(sys.executable), sysconfig.get_path("scripts")]
    dask = shutil.which("dask", path=os.pathsep.join(folders))
    assert dask is not None, f"distributed is installed but no dask command in {folders}"
    paths = assembly(tmp_path / "parts", boxes=200)
    expected = json.loads(local_report(paths, tmp_path))
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, OMP_NUM_THREADS="1")
    processes = _Processes()
    try:
        processes.start(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            env=env,
        )
        worker_args = [dask, "worker", address, "--host", "127.0.0.1", "--nthreads", "1"]
        worker_args += ["--no-dashboard", "--no-nanny"]
        workers = [processes.start(worker_args, env=env) for _ in range(2)]
        _wait_for_workers(address, 2, timeout=120)

        cmd = [sys.executable, "-m", "meshcheck", "--no-config", "--format", "json"]
        cmd += ["--scheduler", address]
        # A whole run on the cluster agrees with the local one.
        first = subprocess.run(
            [*cmd, "--no-cache", *paths], capture_output=True, text=True, timeout=300, env=env
        )
        assert first.returncode == 1, first.stderr  # the overlapping boxes interfere
        assert json.loads(first.stdout) == expected

        # Kill one worker while a run is under way: it completes (tasks retried on the other
        # worker) with the same report, or fails with one line and exit 3; it never hangs.
        run = subprocess.Popen(
            [*cmd, "--no-cache", *paths],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        processes.started.append(run)
        victim = _busy_worker(address, workers, deadline=time.monotonic() + 120)
        assert run.poll() is None  # the run is under way
        os.kill(victim.pid, signal.SIGKILL)
        out, err = run.communicate(timeout=300)
        if run.returncode == 3:
            assert err.startswith(f"error: {address}: ") and err.count("\n") == 1
        else:
            assert run.returncode == first.returncode, err
            assert json.loads(out) == expected
        assert "Traceback" not in err
    finally:
        processes.stop()


def test_the_scheduler_comes_from_the_option_the_environment_or_the_config(tmp_path, monkeypatch):
    from meshcheck.errors import ConfigError
    from meshcheck.settings import Settings

    config = tmp_path / "meshcheck.toml"
    config.write_text('scheduler = "tcp://10.0.0.5:8786"\n')
    assert Settings.from_options(config=config).scheduler == "tcp://10.0.0.5:8786"
    monkeypatch.setenv("MESHCHECK_SCHEDULER", "tcp://10.0.0.6:8786")
    assert Settings.from_options(config=config).scheduler == "tcp://10.0.0.6:8786"
    given = Settings.from_options(config=config, scheduler="tcp://10.0.0.7:8786")
    assert given.scheduler == "tcp://10.0.0.7:8786"
    assert Settings.from_options(config=config, scheduler="").scheduler is None  # run locally
    config.write_text("scheduler = 8786\n")
    with pytest.raises(ConfigError, match="scheduler must be a scheduler address"):
        Settings.from_options(config=config)
