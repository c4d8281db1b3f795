"""Running tasks: local worker processes that never import the caller's script, time limits,
lost workers, and the README's API example run verbatim as a plain script."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time

import pytest

import meshcheck.execute as execute
from meshcheck.execute import Executor, LocalPool, Task, resolve

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def readme_api_example() -> str:
    """The first Python block under README's "Python API" heading, verbatim."""
    with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
        text = f.read()
    section = text[text.index("## Python API") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def _env(tmp_path) -> dict:
    env = dict(os.environ)
    # An empty cache (the bracket is concave: CoACD runs in worker processes) and no
    # configuration file from the user.
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    env["XDG_CONFIG_HOME"] = str(tmp_path / "config")
    env.pop("MESHCHECK_SCHEDULER", None)
    # Two parts never repay CoACD (decompose.coacd_budgets): force it, so workers really run.
    env["MESHCHECK_COACD_BUDGET"] = "300"
    return env


EXPECTED = "touching sample_meshes/bracket.stl sample_meshes/plate.stl 0.0\npassed\n"


@pytest.mark.slow
@pytest.mark.parametrize("how", ["script", "-c", "stdin"])
def test_readme_api_example_runs_without_main_guard(tmp_path, how):
    # With multiprocessing's spawn, workers would re-import the unguarded script,
    # which would call check() again in every worker: hundreds of tracebacks, no end.
    code = readme_api_example()
    assert "__main__" not in code
    script = tmp_path / "example.py"
    script.write_text(code)
    if how == "script":
        args, stdin = [sys.executable, str(script)], None
    elif how == "-c":
        args, stdin = [sys.executable, "-c", code], None
    else:
        args, stdin = [sys.executable, "-"], code
    done = subprocess.run(
        args,
        cwd=ROOT,
        env=_env(tmp_path),
        input=stdin,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout == EXPECTED
    assert "Traceback" not in done.stderr
    # the concave bracket was decomposed in a worker and cached: workers really ran
    assert any(
        name.endswith(".bin") for _, _, files in os.walk(tmp_path / "cache") for name in files
    )


def test_pool_returns_results_in_task_order_and_reuses_workers():
    tasks = [Task((k,), size=k) for k in range(7)]  # largest start first, results in order
    with LocalPool(2) as pool:
        assert pool.map("meshcheck.execute:echo", tasks) == list(range(7))
        pids = {w.process.pid for w in pool.workers}
        assert pool.map("meshcheck.execute:echo", tasks[:3]) == [0, 1, 2]
        assert {w.process.pid for w in pool.workers} == pids


def test_here_this_process_works_beside_one_worker_fewer():
    """``here=True``: the pool starts jobs - 1 workers and this process takes tasks while it
    waits; results stay in task order. With a time limit, or workers enough already, it does
    not (it cannot be stopped, and the cores are taken)."""
    tasks = [Task((0.3,), size=1) for _ in range(8)]
    with LocalPool(2) as pool:
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True)
        assert len(pool.workers) == 1
        assert os.getpid() in pids and set(pids) <= {os.getpid(), pool.workers[0].process.pid}
    with LocalPool(2) as pool:
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True, time_limit=60)
        assert len(pool.workers) == 2 and os.getpid() not in pids
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True)
        assert os.getpid() not in pids  # two workers already: this process only waits
    assert Executor().map("meshcheck.execute:echo", [Task((1,))], here=True) == [1]


def test_a_worker_starts_its_next_task_while_this_process_runs_a_long_one():
    """While this process runs a task it reads no reply; a worker whose reply is larger than
    the pipe holds must still go on to its next task at once, not wait for it."""
    tasks = [  # the worker takes the largest task and the smallest, this process the long one
        Task((0.5, 1 << 20), size=3),
        Task((2.0, 1 << 20), size=2),
        Task((0.5, 1 << 20), size=1),
    ]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        (pid, first, _), (here, long_one, _), (_, second, _) = pool.map(
            "meshcheck.execute:sleep_then_bulk", tasks, here=True
        )
    assert here == os.getpid() != pid
    assert second - first < 1.5  # not after this process's 2 s task: right after its first
    assert second < long_one + 2.0


def test_a_busy_worker_is_sent_its_next_task_and_its_large_values_without_waiting():
    """Before this process runs a task it sends each busy worker its next one, with shared
    values larger than a pipe holds: the worker reads them while it works, so neither it nor
    this process waits for the other."""
    shared = {key: bytes(4 << 20) for key in ("a", "b", "c")}
    tasks = [  # the worker takes the largest task and the smallest, this process the long one
        Task((1.5, "a"), needs=("a",), size=3),
        Task((3.0, "c"), needs=("c",), size=2),
        Task((0.5, "b"), needs=("b",), size=1),
    ]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        begun = time.time()
        (pid, first, _), (here, long_one, size), (_, second, _) = pool.map(
            "meshcheck.execute:sleep_then_shared", tasks, shared=shared, here=True
        )
    assert here == os.getpid() != pid and size == 4 << 20
    assert long_one - begun < 1.0  # not held up until the worker read its next task's value
    assert second - first < 2.3  # the worker's second task right after its first (1.5 s), not
    # after this process's 3 s one


def test_with_no_task_left_this_process_takes_back_the_one_a_busy_worker_has_not_started():
    """The task sent to a busy worker to run after its own is run here once this process has
    none left: the map ends with the worker's task, not after both."""
    tasks = [
        Task((1.5,), size=3),  # the worker's
        Task((0.1,), size=2),  # this process's
        Task((0.6,), size=1),  # sent to the worker to run next, then taken back
    ]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        begun = time.monotonic()
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True)
        took = time.monotonic() - begun
        worker = pool.workers[0]
        assert pids == [worker.process.pid, os.getpid(), os.getpid()]
        assert took < 2.0  # the worker's 1.5 s, not 2.1 s
        assert worker.task is worker.withdrawing is None and not worker.queued
        # The worker serves the next map as before.
        assert pool.map("meshcheck.execute:echo", [Task((k,), size=k) for k in range(4)]) == [
            0,
            1,
            2,
            3,
        ]


def test_tasks_drawn_from_an_iterator_go_to_an_idle_worker_as_each_is_made():
    """An iterator of tasks is drawn from in this process while the map runs: each task made
    goes to an idle worker at once, with the shared values the iterator put for it, and this
    process takes none until the iterator ends. Results stay in the order made."""
    shared: dict = {}
    made_at = []

    def tasks():
        shared["a"] = bytes(3)
        yield Task((0.5, "a"), needs=("a",), size=1)
        time.sleep(1.0)  # making the next task takes long: a screen
        made_at.append(time.time())
        shared["b"] = bytes(5)
        yield Task((0.1, "b"), needs=("b",), size=9)

    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        worker = pool.workers[0].process.pid
        (pid_a, started_a, length_a), (pid_b, _, length_b) = pool.map(
            "meshcheck.execute:sleep_then_shared", tasks(), shared=shared, here=True, grow=False
        )
    assert (length_a, length_b) == (3, 5)
    assert started_a < made_at[0] - 0.5  # the first ran while the second was being made
    assert pid_a == pid_b == worker  # idle when the second was made: it took it too
    # Executor (here, one after another) draws the same way
    shared.clear()
    assert [
        r[2] for r in Executor().map("meshcheck.execute:sleep_then_shared", tasks(), shared=shared)
    ] == [3, 5]
    with LocalPool(2) as pool:
        assert pool.map("meshcheck.execute:echo", iter([])) == []


def _slept_here_and_in_a_worker(tasks: list[Task]) -> tuple[list[int], float, int]:
    """``sleep_then_pid`` of each task, in a map this process helps in with one ready worker:
    the process ids that ran them, the seconds the map took, the worker's process id."""
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        begun = time.monotonic()
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True)
        took = time.monotonic() - begun
        return pids, took, pool.workers[0].process.pid


def test_this_process_starts_on_the_largest_task_the_worker_left_then_takes_the_smallest():
    """The two largest tasks run side by side, not one after the other in the worker; the
    worker is sent the next largest to run after its own, this process takes the smallest."""
    tasks = [Task((0.1,), size=0), Task((1.0,), size=3), Task((1.0,), size=2), Task((0.1,), size=1)]
    pids, took, worker = _slept_here_and_in_a_worker(tasks)
    assert pids == [os.getpid(), worker, os.getpid(), worker]
    assert took < 1.6  # 1.1 s, not 2.0 s and more


def test_a_worker_is_sent_next_tasks_as_large_as_the_one_this_process_runs():
    """This process reads no message while it runs a task: a busy worker is sent enough next
    tasks to last while it does (by ``Task.size``), not one, which it would finish early and
    then wait. Here the sizes mislead (the worker's first task is short, this process's long):
    the worker runs all the short ones while this process runs its one."""
    sizes_and_seconds = [(10, 0.1), (9, 1.5)] + [(2, 0.1)] * 5
    tasks = [Task((seconds,), size=size) for size, seconds in sizes_and_seconds]
    pids, took, worker = _slept_here_and_in_a_worker(tasks)
    assert pids == [worker, os.getpid()] + [worker] * 5
    assert took < 2.1  # this process's 1.5 s, not 1.5 s and two rounds more


def test_a_task_taken_back_after_the_result_before_it_is_pending_again():
    """The worker's answer to a withdraw may come after the result of the task before the one
    asked back, which then looked started: it is pending again, and the worker idle."""
    from meshcheck.execute import _LocalRun

    tasks = [Task((k,), size=k) for k in range(3)]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        run = _LocalRun(pool, "meshcheck.execute:echo", tasks, {}, None, None, 1, here=True)
        worker = pool.workers[0]
        run.pending.clear()
        worker.task, worker.withdrawing = 1, 1  # its result before it came: taken as started
        run.withdrawn(worker, True)
        assert worker.task is None and list(run.pending) == [1]
        worker.queued.extend([(0, 0), (2, 0)])  # the last asked back while queued
        worker.withdrawing = 2
        run.withdrawn(worker, True)
        assert list(worker.queued) == [(0, 0)] and list(run.pending) == [1, 2]
        worker.withdrawing = 0  # started already: it stays the worker's
        run.withdrawn(worker, False)
        assert list(worker.queued) == [(0, 0)] and worker.withdrawing is None
        assert list(run.pending) == [1, 2]
        # While it is asked to give one back, it is sent no other: it drops the last it was sent.
        worker.task, worker.withdrawing = 1, 0
        assert not run._queue_short(worker, Task((0,), size=99))
        worker.withdrawing = None
        assert run._queue_short(worker, Task((0,), size=99))
        worker.task = None
        worker.queued.clear()


def test_a_worker_gives_back_only_a_task_it_has_not_started():
    import queue

    from meshcheck._worker import _Messages

    messages = _Messages.__new__(_Messages)
    messages.queue = queue.Queue()
    for message in (("put", "a", 1), ("run", "f", (), ()), ("put", "b", 2)):
        messages.queue.put(message)
    assert messages._withdraw() is True
    assert list(messages.queue.queue) == [("put", "a", 1), ("put", "b", 2)]
    assert messages._withdraw() is False


def test_a_worker_holding_pythons_lock_does_not_hold_this_process_up():
    """A worker inside one long call that holds Python's lock (OpenCASCADE's booleans do) reads
    no message until it returns: the value of its next task, larger than a pipe holds, is
    written by a thread of this process, which runs its own task meanwhile."""
    shared = {key: bytes(4 << 20) for key in ("a", "b", "c")}
    tasks = [  # the worker takes the largest task and the smallest, this process the other
        Task((120_000_000, "a"), needs=("a",), size=3),  # about 1.5 s in one call
        Task((1, "c"), needs=("c",), size=2),
        Task((1, "b"), needs=("b",), size=1),
    ]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        begun = time.time()
        (pid, first, _), (here, small, size), _ = pool.map(
            "meshcheck.execute:hold_then_shared", tasks, shared=shared, here=True
        )
        ended = time.time()
    assert here == os.getpid() != pid and size == 4 << 20
    assert ended - first > 0.5  # the worker's call held it that long
    assert small - begun < 0.4  # this process ran its task at once, not after that call


def test_a_busy_workers_next_task_that_fits_its_pipe_is_written_before_this_process_runs_one():
    """A busy worker inside one call that holds Python's lock reads nothing until it returns,
    and this process's writing thread does not run while this process is inside such a call of
    its own: the next task sent to the worker, with a value larger than a default pipe holds
    but not than its widened one (``PIPE_BYTES``), is written in full first, so the worker
    starts it as soon as its own call is done, not once this process's is."""
    shared = {"a": b"", "b": bytes(512 << 10)}
    tasks = [
        Task((40_000_000, "a"), needs=("a",), size=3),  # the worker's: about 0.7 s in one call
        Task((120_000_000, "a"), needs=("a",), size=2),  # this process's: about 2 s
        Task((1, "b"), needs=("b",), size=1),  # sent to the worker to run next
    ]
    with LocalPool(2) as pool:
        pool.map("meshcheck.execute:echo", [Task((0,))])  # started and ready
        assert pool.workers[0].pipe_bytes >= (512 << 10) + execute.PIPE_SPARE
        (pid, _, _), (here, mine, _), (next_pid, second, size) = pool.map(
            "meshcheck.execute:hold_then_shared", tasks, shared=shared, here=True
        )
        ended = time.time()
    assert here == os.getpid() != pid == next_pid and size == 512 << 10
    assert ended - mine > 1.0  # this process's call held it that long
    assert second < ended - 0.5  # the worker's next task began long before that call ended


def test_the_command_and_its_workers_collect_garbage_less_often_than_a_library_user():
    """The command's process and its workers pass over the collector's
    youngest generation every ``COLLECTOR_THRESHOLD`` allocations (the imports of OpenCASCADE,
    numpy and trimesh allocate hundreds of thousands of lasting objects); a program that
    imports meshcheck as a library keeps Python's default."""
    from meshcheck._process import COLLECTOR_THRESHOLD

    def threshold(code: str) -> int:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return int(done.stdout)

    show = "import gc; print(gc.get_threshold()[0])"
    assert threshold(f"import meshcheck.__main__; {show}") == COLLECTOR_THRESHOLD
    assert threshold(f"import meshcheck, meshcheck.execute; {show}") == 700
    with LocalPool(3) as pool:  # tasks in the workers only (``here`` is False)
        found = pool.map("meshcheck.execute:collector_threshold", [Task(())] * 4)
    assert {t[0] for t in found} == {COLLECTOR_THRESHOLD}
    execute.start_early("collector", "meshcheck.execute:collector_threshold", ())
    assert execute.take_early("collector")[0] == COLLECTOR_THRESHOLD


def test_imports_run_uncollected_then_what_they_made_is_frozen():
    """``imports_uncollected``: no collection inside the block; after it, every object made so
    far is frozen, and the collector is as it was (on, or off), after an error too."""
    import gc

    from meshcheck._process import imports_uncollected

    was_enabled = gc.isenabled()
    try:
        gc.enable()
        before = gc.get_freeze_count()
        with imports_uncollected():
            assert not gc.isenabled()
            made = [[] for _ in range(1000)]  # lists: objects the collector tracks
        assert gc.isenabled()
        assert gc.get_freeze_count() >= before + len(made)
        with pytest.raises(ValueError), imports_uncollected():
            raise ValueError
        assert gc.isenabled()
        gc.disable()
        with imports_uncollected():
            pass
        assert not gc.isenabled()  # off stays off
    finally:
        gc.unfreeze()
        if was_enabled:
            gc.enable()


def test_prepared_workers_import_before_their_first_task():
    """``prepare`` starts the workers a map with this process helping wants (jobs - 1), each
    calling the function before it is ready; a worker started by a map calls none."""
    ask = [Task(("OCP.OCP",))]  # the extension holding every OpenCASCADE module
    with LocalPool(2) as pool:
        pool.prepare("meshcheck.load.step.tessellate:preload")
        assert len(pool.workers) == 1 and pool.prepared == {
            "meshcheck.load.step.tessellate:preload"
        }
        assert pool.map("meshcheck.execute:is_imported", ask) == [True]
    with LocalPool(2) as pool:
        assert pool.map("meshcheck.execute:is_imported", ask) == [False]
        assert pool.prepared == frozenset()
    pool = LocalPool(2)
    pool.prepare("meshcheck.load.step.tessellate:preload")
    started = time.monotonic()
    pool.close()  # not used (a warm run): not waited for while it imports
    assert time.monotonic() - started < 0.5


def test_a_map_that_does_not_grow_runs_on_the_workers_already_started():
    """``grow=False``: the tasks go to the started worker, none is started beside it; a map
    that grows starts the pool's others."""
    with LocalPool(3) as pool:
        (started,) = pool.map("meshcheck.execute:sleep_then_pid", [Task((0.0,))])  # one worker
        tasks = [Task((0.05,)) for _ in range(4)]
        assert pool.map("meshcheck.execute:sleep_then_pid", tasks, grow=False) == [started] * 4
        assert len(pool.workers) == 1
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks)
        assert len(pool.workers) == 3 and len(set(pids)) > 1


def test_a_worker_whose_prepare_fails_leaves_quietly_and_is_replaced(capfd):
    """A prepare function that raises (here: called without its argument) ends its worker
    before it is ready, with no traceback on the user's terminal; the pool starts a worker
    without it, and the map's results are whole."""
    with LocalPool(2) as pool:
        pool.prepare("meshcheck.execute:resolve")
        tasks = [Task((0.5, k)) for k in range(3)]  # long enough to see the first one die
        assert pool.map("meshcheck.execute:sleep_then_echo", tasks) == [0, 1, 2]
        assert pool.failed_starts == 1 and pool.prepared == frozenset()
    assert "Traceback" not in capfd.readouterr().err


def test_a_worker_started_early_joins_the_pool_that_takes_its_result():
    """``start_early`` runs one task before any pool exists; ``take_early`` gives its result
    and the pool adopts the worker (prepared as it was), counted in ``prepare``; a pool with no
    room, or no pool, stops it; ``stop_early`` kills a worker whose result nobody took."""
    from meshcheck.execute import has_early, start_early, stop_early, take_early

    preload = "meshcheck.load.step.tessellate:preload"
    start_early("a", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload)
    with LocalPool(2) as pool:
        pool.prepare(preload)  # the early worker is the one it wants
        assert pool.workers == [] and pool.prepared == {preload}
        pid = take_early("a", pool)
        assert not has_early("a")
        assert [w.process.pid for w in pool.workers] == [pid] and pool.prepared == {preload}
        ask = [Task(("OCP.OCP",))]
        assert pool.map("meshcheck.execute:is_imported", ask) == [True]
        start_early("b", "meshcheck.execute:echo", (2,))
        assert take_early("b", pool) == 2  # no room left: stopped
        assert len(pool.workers) == 1
    assert take_early("a") is None  # taken already
    start_early("c", "meshcheck.execute:sleep_then_echo", (30.0, 3))
    from meshcheck.execute import _EARLY

    process = _EARLY["c"].process
    stop_early()
    assert process.wait(timeout=5) is not None and not has_early("c")


def test_a_workers_task_is_written_to_it_before_this_process_runs_one(monkeypatch):
    """This process runs a task of its own only once the task it gave an idle worker is
    written, with the shared value it needs (its writing thread does not run while this
    process is inside one long call): else the worker waits idle that long."""
    import meshcheck.execute as execute

    seen = []
    with LocalPool(2) as pool:
        assert pool.map("meshcheck.execute:echo", [Task((0,))]) == [0]  # a ready worker

        def here(store, value):
            (worker,) = pool.workers
            seen.append(worker._writer.written >= worker.task_sent > 0)
            return value

        monkeypatch.setattr(execute, "echo", here)  # this process's tasks, not the worker's
        tasks = [Task((1,), ("blob",), size=2), Task((2,), ("blob",), size=1)]
        blob = b"x" * (16 << 20)
        assert pool.map("meshcheck.execute:echo", tasks, shared={"blob": blob}, here=True) == [1, 2]
    assert seen == [True]


def test_a_spare_worker_takes_the_first_early_task_it_was_started_for():
    """``start_spare`` starts a worker before its task is known: the next ``start_early`` with
    its ``prepare`` and ``twin`` sends the task to it, without a second start; one with other
    imports, or ``stop_spare``, kills it."""
    from meshcheck.execute import (
        _EARLY,
        _SPARE,
        start_early,
        start_spare,
        stop_early,
        stop_spare,
        take_early,
    )

    preload = "meshcheck.load.step.tessellate:preload"
    start_spare(preload)
    spare = _SPARE[(preload, False)].process
    start_early("a", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload)
    assert _EARLY["a"].process is spare and not _SPARE
    assert take_early("a") == spare.pid
    start_spare(preload)
    other = _SPARE[(preload, False)].process
    start_early("b", "meshcheck.execute:echo", (2,))  # no imports asked: a worker of its own
    assert other.wait(timeout=5) is not None and not _SPARE
    assert _EARLY["b"].process is not other and take_early("b") == 2
    start_spare()
    unused = _SPARE[(None, False)].process
    stop_spare()
    assert unused.wait(timeout=5) is not None and not _SPARE
    stop_early()


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat", encoding="ascii") as f:
        return int(f.read().rsplit(")", 1)[1].split()[1])


def _is_gone(pid: int) -> bool:
    """No process ``pid`` runs (none, or one that exited and waits for a parent to reap it)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


@pytest.mark.linux_only
def test_an_early_worker_forks_a_twin_that_waits_in_the_pools_reserve():
    """``twin=True``: once its prepare imports are made, the early worker forks a second
    worker that has them (not this process's child). The pool keeps it in reserve: a map this
    process helps in leaves it out (no more than ``jobs`` processes take tasks), a map it does
    not help in takes it instead of starting a worker; closing the pool ends both."""
    from meshcheck.execute import start_early, take_early

    preload = "meshcheck.load.step.tessellate:preload"
    start_early("t", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    tasks = [Task((0.2,)) for _ in range(4)]
    with LocalPool(2) as pool:
        first = take_early("t", pool)
        assert [w.process.pid for w in pool.workers] == [first] and len(pool.reserve) == 1
        helped = pool.map("meshcheck.execute:sleep_then_pid", tasks, here=True)
        assert set(helped) == {first, os.getpid()} and len(pool.reserve) == 1
        pids = pool.map("meshcheck.execute:sleep_then_pid", tasks, grow=False)
        (twin,) = set(pids) - {first}
        assert pool.started == len(pool.workers) == 2 and pool.reserve == []
        assert _parent(twin) == first
        with open(f"/proc/{twin}/maps", encoding="utf-8") as f:  # OpenCASCADE's extension
            assert "/OCP." in f.read()
    assert _is_gone(first) and _is_gone(twin)


@pytest.mark.linux_only
def test_a_twin_is_killed_with_its_unclaimed_worker_and_when_it_overruns():
    """``stop_early`` ends an early worker's twin with it; a twin whose task overruns is
    killed (by its process id: it is no child of this process) and the map goes on."""
    from meshcheck.execute import _EARLY, start_early, stop_early, take_early

    preload = "meshcheck.load.step.tessellate:preload"
    start_early("u", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    worker = _EARLY["u"]
    assert worker.receive_end.poll(30)  # its imports are made: the twin is forked
    twin = worker.twin
    stop_early()
    assert twin.process.pid is not None and _is_gone(twin.process.pid)
    assert _is_gone(worker.process.pid)

    start_early("v", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    tasks = [Task((30.0, "slow")), Task((30.0, "slower")), Task((0.0, "quick"))]
    started = time.monotonic()
    with LocalPool(2) as pool:
        take_early("v", pool)
        forked = pool.reserve[0]
        out = pool.map("meshcheck.execute:sleep_then_echo", tasks, time_limit=2.0)
        assert out == [None, None, "quick"] and forked not in pool.workers
        assert _is_gone(forked.process.pid)
    assert time.monotonic() - started < 25


@pytest.mark.linux_only
def test_a_twin_sent_more_imports_while_its_worker_works_takes_its_place():
    """``prepare_twin_early`` while the early worker's task runs: the twin imports what the
    worker's task did not need (trimesh, for the welds of a large STEP file's meshes), beside
    it, and serves the pool in its place; the worker waits in reserve. Once the worker's
    result is in, the twin is not sent it (it would be late, not early)."""
    from meshcheck.execute import prepare_twin_early, start_early, take_early

    preload = "meshcheck.load.step.tessellate:preload"
    welding = "meshcheck.load.step.tessellate:preload_welding"
    start_early("p", "meshcheck.execute:sleep_then_pid", (3.0,), prepare=preload, twin=True)
    assert prepare_twin_early("p", welding)
    with LocalPool(2) as pool:
        first = take_early("p", pool)
        (twin,) = pool.workers
        assert pool.reserve[0].process.pid == first != twin.process.pid
        asked = [Task(("trimesh",))]  # one task: the pool's one worker takes it
        assert pool.map("meshcheck.execute:is_imported", asked, grow=False) == [True]
        assert twin.preparing is False and twin.task is None
        assert pool.map("meshcheck.execute:sleep_then_pid", [Task((0.0,))] * 3, here=True)
    assert _is_gone(first) and _is_gone(twin.process.pid)

    start_early("q", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    from meshcheck.execute import _EARLY

    worker = _EARLY["q"]
    while not worker.receive_end.poll(0.05) or not worker.is_ready:  # its result in
        if worker.receive_end.poll(0):
            worker.ready(worker.receive_end.recv())
    assert not prepare_twin_early("q", welding)
    with LocalPool(2) as pool:
        first = take_early("q", pool)
        assert [w.process.pid for w in pool.workers] == [first] and len(pool.reserve) == 1
        asked = [Task(("trimesh",))]
        assert pool.map("meshcheck.execute:is_imported", asked, grow=False) == [False]


@pytest.mark.linux_only
@pytest.mark.posix_only
def test_a_twins_cpu_time_counts_in_this_processs_children():
    """The twin is its worker's child: the worker reaps it as it leaves (the pool stops twins
    first), so its CPU time counts in the worker's and then in this process's children, where a
    benchmark measures a run's CPU."""
    import resource

    from meshcheck.execute import start_early, take_early

    def children() -> float:
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    before = children()
    preload = "meshcheck.load.step.tessellate:preload"
    start_early("c", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    with LocalPool(2) as pool:
        take_early("c", pool)
        spun = pool.map("meshcheck.execute:spin_then_cpu", [Task((0.5,))] * 2, grow=False)
        assert len({pid for pid, _ in spun}) == 2  # the worker and its twin
    assert children() - before >= sum(cpu for _, cpu in spun)


def test_no_twin_where_this_process_cannot_hold_one_by_a_pidfd(monkeypatch):
    """A twin that could be neither killed nor awaited (no pidfds: macOS, Windows, a sandbox
    refusing them) is not forked: the early worker is the pool's one worker, as without it."""
    from meshcheck import execute
    from meshcheck.execute import start_early, take_early

    monkeypatch.setattr(execute, "_has_pidfds", lambda: False)
    preload = "meshcheck.load.step.tessellate:preload"
    start_early("w", "meshcheck.execute:sleep_then_pid", (0.0,), prepare=preload, twin=True)
    with LocalPool(2) as pool:
        first = take_early("w", pool)
        assert pool.reserve == [] and pool.started == 1
        tasks = [Task((0.1,))] * 2
        assert pool.map("meshcheck.execute:sleep_then_pid", tasks, grow=False) == [first] * 2


def test_shared_values_travel_once_per_worker():
    shared = {"m": list(range(1000))}
    tasks = [Task(("m",), needs=("m",)) for _ in range(6)]
    with LocalPool(1) as pool:
        assert pool.map("meshcheck.execute:shared_length", tasks, shared=shared) == [1000] * 6
        assert pool.workers[0].keys == {"m"}


def test_overrun_gives_none_and_the_pool_goes_on():
    tasks = [Task((30.0, "slow")), Task((0.0, "quick")), Task((0.0, "next"))]
    started = time.monotonic()
    with LocalPool(1) as pool:
        out = pool.map("meshcheck.execute:sleep_then_echo", tasks, time_limit=3.0)
    assert out[1:] == ["quick", "next"]
    assert out[0] is None
    assert time.monotonic() - started < 25


def test_a_dead_worker_gives_none_and_is_replaced():
    with LocalPool(1) as pool:
        out = pool.map("meshcheck.execute:exit_worker", [Task((3,))])
        assert out == [None]
        assert pool.map("meshcheck.execute:echo", [Task(("alive",))]) == ["alive"]


def test_a_worker_that_dies_while_tasks_are_drawn_gives_none_and_is_replaced():
    def tasks():
        yield Task((3,))
        time.sleep(0.5)  # the worker dies while the next task is made
        yield Task((4,))

    with LocalPool(1) as pool:
        assert pool.map("meshcheck.execute:exit_worker", tasks()) == [None, None]
        assert pool.map("meshcheck.execute:echo", iter([Task(("alive",))])) == ["alive"]


def test_a_bug_in_a_task_raises_with_the_workers_traceback():
    with LocalPool(1) as pool, pytest.raises(RuntimeError, match="ZeroDivisionError"):
        pool.map("meshcheck.execute:echo_inverse", [Task((0,))])


def test_only_meshcheck_functions_run():
    with pytest.raises(ValueError, match="not a meshcheck function"):
        resolve("os:system")
    with pytest.raises(ValueError):
        Executor().map("subprocess:run", [Task((["true"],))])


def test_workers_that_cannot_start_are_one_error_not_a_loop(monkeypatch):
    from meshcheck.errors import ExecutionError

    # a Python that cannot import meshcheck's worker: it exits at once
    monkeypatch.setattr(sys, "executable", "/bin/false")
    with LocalPool(1) as pool, pytest.raises(ExecutionError, match="exit before they start"):
        pool.map("meshcheck.execute:echo", [Task((1,))])


def test_workers_import_this_meshcheck_not_one_in_the_working_directory(tmp_path, monkeypatch):
    """Run from a directory holding another ``meshcheck`` (a source checkout whose kernels were
    never built, as CI's first command is run): the workers still import the caller's."""
    impostor = tmp_path / "meshcheck"
    impostor.mkdir()
    (impostor / "__init__.py").write_text("raise ImportError('the wrong meshcheck')\n")
    monkeypatch.chdir(tmp_path)
    with LocalPool(1) as pool:
        assert pool.map("meshcheck.execute:echo", [Task((7,))]) == [7]
