"""One map of tasks over this process, a local process pool, or a Dask cluster.

The stages that are independent per item (decomposing a mesh, verifying a chunk of part pairs)
hand their work to ``Executor.map``: a named meshcheck function, a list of ``Task``\\ s, and the
``shared`` values (meshes) the tasks read by key. Results come back in task order, whatever ran
where, so the report does not depend on how the work was spread.

- ``Executor`` (``jobs=1``, or few tasks) runs the tasks here, one after another.
- ``LocalPool`` keeps worker processes started as ``python -m meshcheck._worker``: fresh
  interpreters that never import the caller's main module, so ``meshcheck.check`` works from a
  script without a ``__main__`` guard, ``python -c``, stdin or a notebook. Each shared value is sent
  to a worker once, the first time a task there needs it. A task that overruns ``time_limit`` or
  kills its worker (CoACD crashes) gives None, and the worker is replaced.
- ``DaskExecutor`` submits the tasks to a Dask distributed cluster; each shared value is scattered
  to the cluster once. Dask is imported only here, only when a scheduler address is given.

Functions are sent by name (``"meshcheck.decompose:decompose_task"``) and must live in meshcheck;
each is called as ``function(store, *args)``, ``store`` mapping keys to shared values (it may also
keep per-process memos under keys of its own).
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import math
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from dataclasses import dataclass

from .errors import ExecutionError

# Environment of local workers: one thread per process for every threaded library, so jobs
# processes use jobs cores and no more (CoACD's OpenMP would otherwise take every core each).
_ONE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


@dataclass(frozen=True)
class Task:
    """One call of the mapped function.

    Attributes
    ----------
    args : tuple
        Positional arguments after the store; picklable.
    needs : tuple
        Keys of the shared values the call reads from its store.
    size : int
        Rough cost, for ordering: the largest tasks start first.
    time_limit : float, optional
        Seconds this task may run, instead of the map's ``time_limit`` (local pools only).
    """

    args: tuple
    needs: tuple[Hashable, ...] = ()
    size: int = 0
    time_limit: float | None = None


def default_jobs() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def resolve(function: str) -> Callable:
    """The meshcheck function named ``"meshcheck.module:name"``; nothing outside meshcheck."""
    module, _, name = function.partition(":")
    if not (module == "meshcheck" or module.startswith("meshcheck.")) or not name:
        raise ValueError(f"not a meshcheck function: {function!r}")
    return getattr(importlib.import_module(module), name)


def call(function: str, store: dict, needs: Sequence[Hashable], args: tuple):
    """Run one task: ``function(store, *args)`` after checking the store holds ``needs``."""
    missing = [k for k in needs if k not in store]
    if missing:
        raise KeyError(f"shared values not sent: {missing[:3]}")
    return resolve(function)(store, *args)


class Executor:
    """Runs tasks in this process, one after another; the base of the other executors.

    Parameters
    ----------
    jobs : int
        Processes the executor may use (1 here).

    Examples
    --------
    >>> ex = Executor()
    >>> ex.map("meshcheck.execute:echo", [Task((1,)), Task((2,))])
    [1, 2]
    """

    jobs = 1
    is_distributed = False
    #: Indices (into the current map's tasks) of the tasks running now, for progress lines.
    running: tuple[int, ...] = ()

    #: The ``prepare`` functions every running worker has called.
    prepared: frozenset[str] = frozenset()

    @property
    def is_started(self) -> bool:
        """True when worker processes are already running (a map then costs no start-up)."""
        return False

    def prepare(self, function: str) -> None:
        """Start the workers a map will want now, each calling ``function`` (``module:name``,
        no arguments: imports) before it takes a task, while this process loads the inputs.
        Nothing here, nor on a cluster."""

    def map(
        self,
        function: str,
        tasks: Iterable[Task],
        *,
        shared: dict | None = None,
        progress: Callable[[int], None] | None = None,
        time_limit: float | None = None,
        here: bool = False,
        grow: bool = True,
    ) -> list:
        """Results of ``function`` on each task, in task order.

        Parameters
        ----------
        function : str
            ``"meshcheck.module:name"``, called as ``name(store, *task.args)``.
        tasks : sequence or iterator of Task
            An iterator is drawn from in this process while the map runs: making a task may
            take work (a screen), and each task made goes to an idle worker at once
            (``LocalPool``), before this process takes any. It may put the shared values a task
            needs into ``shared`` before it gives the task.
        shared : dict, optional
            Values tasks read by key (``Task.needs``).
        progress : callable, optional
            Called with the number of tasks finished, as they finish.
        time_limit : float, optional
            Seconds a task may run; a task that overruns gives None. Enforced by killing the
            worker, so only where tasks run in other processes (here: ignored).
        here : bool
            This process may take tasks too, while it waits (``LocalPool``: it then starts one
            worker fewer; only for maps without time limits). The results are the same.
        grow : bool
            ``LocalPool``: False when only the workers already started take the tasks (one is
            started if none is); the others would start and import first. The results are the
            same.
        """
        shared = {} if shared is None else shared
        store, out = dict(shared), []
        for done, task in enumerate(tasks, start=1):
            for key in task.needs:  # put into ``shared`` by an iterator as it made the task
                if key not in store and key in shared:
                    store[key] = shared[key]
            self.running = (done - 1,)
            out.append(call(function, store, task.needs, task.args))
            self.running = ()
            if progress is not None:
                progress(done)
        return out

    def close(self) -> None:
        """Stop any processes the executor started."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def echo(store: dict, value):
    """A task that returns its argument (for tests and examples)."""
    return value


def shared_length(store: dict, key):
    """A task that returns the length of a shared value (for tests)."""
    return len(store[key])


def echo_inverse(store: dict, value):
    """A task that returns ``1 / value`` (for tests of failing tasks)."""
    return 1 / value


def sleep_then_echo(store: dict, seconds: float, value):
    """A task that sleeps, then returns its argument (for tests of time limits)."""
    time.sleep(seconds)
    return value


def sleep_then_pid(store: dict, seconds: float):
    """A task that sleeps, then returns the id of the process it ran in (for tests)."""
    time.sleep(seconds)
    return os.getpid()


def sleep_then_bulk(store: dict, seconds: float, size: int) -> tuple[int, float, bytes]:
    """A task that notes when it starts, sleeps, then returns the id of its process, that
    time and ``size`` bytes (for tests of replies larger than a pipe's buffer)."""
    started = time.time()
    time.sleep(seconds)
    return os.getpid(), started, bytes(size)


def sleep_then_shared(store: dict, seconds: float, key) -> tuple[int, float, int]:
    """A task that notes when it starts, sleeps, then returns the id of its process, that
    time and the length of a shared value (for tests of values larger than a pipe's buffer)."""
    started = time.time()
    time.sleep(seconds)
    return os.getpid(), started, len(store[key])


def hold_then_shared(store: dict, count: int, key) -> tuple[int, float, int]:
    """A task that notes when it starts, then sums ``range(count)`` in one call that holds
    Python's lock throughout (as a long OpenCASCADE call does), then returns the id of its
    process, that time and the length of a shared value (for tests)."""
    started = time.time()
    sum(range(count))
    return os.getpid(), started, len(store[key])


def spin_then_cpu(store: dict, seconds: float) -> tuple[int, float]:
    """A task that spins for ``seconds`` of CPU, then returns the id of its process and the CPU
    seconds that process has used (for tests)."""
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass
    return os.getpid(), time.process_time()


def collector_threshold(store: dict) -> tuple[int, ...]:
    """A task that returns its process's garbage collector thresholds (for tests)."""
    import gc

    return gc.get_threshold()


def is_imported(store: dict, module: str) -> bool:
    """A task that says whether its process has imported ``module`` (for tests)."""
    return module in sys.modules


def exit_worker(store: dict, code: int):
    """A task that ends its process at once (for tests of lost workers)."""
    os._exit(code)


class Writer:
    """Messages to the other end of a pipe, in order, written by a thread of their own: the
    worker's replies to its parent, and the parent's messages to each worker
    (``_Worker.send``).

    A message larger than the pipe's buffer blocks its writer until the other end reads it. The
    parent reads nothing while it runs a task itself (``_LocalRun.run_here``), and a
    worker's reading thread runs only when Python lets it, which a task inside one long
    OpenCASCADE call (a boolean, a mesh) does not until the call returns: written by the caller,
    either would wait for the other."""

    def __init__(self, connection):
        import queue
        import threading

        self.connection, self.queue, self.is_broken = connection, queue.Queue(), False
        self.put_count = self.written = 0  # messages queued, and written, so far
        self.put_bytes = 0  # the pickled bytes of the messages queued so far
        self.condition = threading.Condition()
        self.thread = threading.Thread(target=self._write, daemon=True)
        self.thread.start()

    def put(self, message) -> bool:
        """Queue ``message``, pickled here (so its size is known: ``put_bytes``); False once the
        other end is gone (a write failed)."""
        from multiprocessing.reduction import ForkingPickler

        payload = ForkingPickler.dumps(message)
        self.put_count += 1
        self.put_bytes += len(payload)
        self.queue.put(payload)
        return not self.is_broken

    def wait_written(self, count: int, timeout: float) -> bool:
        """Wait until the first ``count`` messages are written, or writing failed, at most
        ``timeout`` seconds; whether they are."""
        with self.condition:
            return self.condition.wait_for(lambda: self.written >= count or self.is_broken, timeout)

    def close(self, timeout: float | None = None) -> bool:
        """Write the messages queued, then stop; False when that takes over ``timeout`` seconds
        (the other end does not read)."""
        self.queue.put(None)
        self.thread.join(timeout)
        return not self.thread.is_alive()

    def _write(self) -> None:
        while (message := self.queue.get()) is not None:
            try:
                self.connection.send_bytes(message)
            except (BrokenPipeError, OSError):
                with self.condition:
                    self.is_broken = True
                    self.condition.notify_all()
                return
            message = None  # not kept while it waits for the next (a mesh, a product's text)
            with self.condition:
                self.written += 1
                self.condition.notify_all()


class _Worker:
    """One ``python -m meshcheck._worker`` process and its two pipe ends; ``prepare``: a
    function it calls before it says it is ready (``Executor.prepare``).

    Messages to it are written by a thread of its own (``send``, ``Writer``): this
    process never waits on the pipe, not even for a worker inside one long OpenCASCADE call,
    which reads nothing until the call returns."""

    def __init__(self, prepare: str | None = None, *, twin: bool = False):
        import subprocess

        env = dict(os.environ)
        env.update(dict.fromkeys(_ONE_THREAD, "1"))
        # The worker imports this very meshcheck, wherever it was imported from; -P keeps
        # ``-m`` from putting the working directory first, where a source checkout (without its
        # compiled kernels) or any folder named meshcheck would be imported instead.
        package_root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
        arguments = [prepare] if prepare else []
        # A twin is killed and awaited through a pidfd: none without them.
        twin = twin and bool(prepare) and _has_pidfds()
        to_twin, from_twin = (os.pipe(), os.pipe()) if twin else ((), ())
        passed = (to_twin[0], from_twin[1]) if to_twin else ()
        if passed:
            arguments.append(f"{passed[0]},{passed[1]}")
        try:
            process = subprocess.Popen(
                [sys.executable, "-P", "-m", "meshcheck._worker", *arguments],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                env=env,
                close_fds=True,
                pass_fds=passed,
            )
        except BaseException:
            for end in (*to_twin, *from_twin):
                os.close(end)
            raise
        self._connect(
            process, os.dup(process.stdin.fileno()), os.dup(process.stdout.fileno()), prepare
        )
        process.stdin.close()
        process.stdout.close()
        if passed:
            for end in passed:  # the worker's and its twin's now
                os.close(end)
            self.twin = _Worker.__new__(_Worker)  # started by the worker, not here
            self.twin._connect(_Forked(), to_twin[1], from_twin[0], prepare)

    def _connect(self, process, send: int, receive: int, prepare: str | None) -> None:
        """Talk to the worker ``process`` over the pipe ends ``send`` and ``receive`` (file
        descriptors this object owns from now on)."""
        from multiprocessing.connection import Connection

        self.process = process
        #: The worker it forks once its ``prepare`` imports are made (``twin=True``), not started
        #: by this process: it serves it over pipes made here, the worker's imports loaded.
        self.twin: _Worker | None = None
        self.send_end = Connection(send, readable=False)
        self.receive_end = Connection(receive, writable=False)
        self.keys: set = set()
        self.task: int | None = None  # index of the task running, None when idle
        #: The tasks sent to run after it (``run_here``), in order: (index, how many messages
        #: and how many bytes it had been sent with that task's).
        self.queued: deque[tuple[int, int, int]] = deque()
        self.task_sent = 0  # how many messages it had been sent with its task's
        #: How many bytes it had been sent with its task's (``bytes_sent``): the ones sent
        #: since lie in the pipe at most, unread while it runs its task.
        self.task_bytes = 0
        #: How many bytes its pipe holds unread: a message up to that is written in full while
        #: it runs a task and reads nothing (``_LocalRun.written_to_workers``).
        self.pipe_bytes = _widened_pipe(send)
        self.withdrawing: int | None = None  # the queued task asked back, until it answers
        self.started = 0.0
        self.is_ready = False
        self.prepare = prepare
        #: Sent imports to make besides ``prepare`` (``prepare_twin_early``): their reply is
        #: still to come (``preparing``), or has come (``more_prepared``).
        self.preparing = self.more_prepared = False
        self._writer = Writer(self.send_end)

    def ready(self, message: tuple) -> None:
        """Take the worker's ready message (``("ready", pid)``): a twin's names its process."""
        self.is_ready = True
        if self.is_twin:
            self.process.found(message[1])

    @property
    def is_twin(self) -> bool:
        """Forked by another worker (``twin``), not started by this process."""
        return isinstance(self.process, _Forked)

    def fileno(self) -> int:
        return self.receive_end.fileno()

    @property
    def sent(self) -> int:
        """How many messages it has been sent (``send``), written or not yet."""
        return self._writer.put_count

    def wait_written(self, count: int, timeout: float) -> bool:
        """Wait until its first ``count`` messages are written, at most ``timeout`` seconds."""
        return self._writer.wait_written(count, timeout)

    @property
    def bytes_sent(self) -> int:
        """How many bytes it has been sent (``send``), pickled, written or not yet."""
        return self._writer.put_bytes

    def send(self, message) -> None:
        """Queue ``message`` for the worker, in order; its writing thread sends it.

        Raises
        ------
        BrokenPipeError
            An earlier message found the worker gone.
        """
        if not self._writer.put(message):
            raise BrokenPipeError("the worker is gone")

    def kill(self) -> None:
        """Kill the worker, then its twin, when no pool took that (``LocalPool.adopt``): the
        worker may still be making the imports it forks the twin after, which ``_find_twin``
        would wait for."""
        self._find_twin()
        self.process.kill()
        self.process.wait()
        self._writer.close()  # a write to a worker that is gone fails at once
        self.send_end.close()
        self.receive_end.close()
        if self.twin is not None:
            self.twin.kill()

    def stop(self, timeout: float = 5.0) -> None:
        """Close the pipe (the worker exits at EOF); kill it if it does not. Its twin, when no
        pool took that, first (this worker then reaps it)."""
        import subprocess

        if self.twin is not None:
            self.twin.stop(timeout)
        self._find_twin(timeout)
        if not self._writer.close(timeout):  # it does not read: stuck in a task
            self.process.kill()
            self._writer.close()
        self.send_end.close()
        try:
            self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.receive_end.close()

    def _find_twin(self, timeout: float = 5.0) -> None:
        """A twin that has not been heard from: read its ready message (its process id, which
        it sends before it reads anything), so it can be killed and its exit awaited. Its end of
        the stream (its worker died before forking it) leaves nothing to wait for."""
        if self.is_ready or not self.is_twin:
            return
        try:
            if self.receive_end.poll(timeout):
                message = self.receive_end.recv()
                if message[0] == "ready":
                    self.ready(message)
        except (EOFError, OSError):
            pass


#: Bytes asked for each pipe to a worker (``_widened_pipe``): Linux's default upper bound for an
#: unprivileged process (``/proc/sys/fs/pipe-max-size``), sixteen times the default buffer.
PIPE_BYTES = 1 << 20
#: Bytes of a pipe left spare by the messages waited for (``_LocalRun.written_to_workers``): each
#: message's length header, and what ``F_GETPIPE_SZ`` rounds.
PIPE_SPARE = 1 << 12


def _widened_pipe(end: int) -> int:
    """Widen the buffer of the pipe whose write end is ``end`` to ``PIPE_BYTES`` where the
    system lets this process (Linux); the bytes it holds now."""
    import fcntl
    import select

    setter, getter = getattr(fcntl, "F_SETPIPE_SZ", None), getattr(fcntl, "F_GETPIPE_SZ", None)
    if setter is not None and getter is not None:
        with contextlib.suppress(OSError):
            fcntl.fcntl(end, setter, PIPE_BYTES)
        with contextlib.suppress(OSError):
            return int(fcntl.fcntl(end, getter))
    return select.PIPE_BUF  # what POSIX guarantees a pipe holds


@functools.cache
def _has_pidfds() -> bool:
    """Whether this process can hold another by a pidfd: Linux 5.3 or later, and not refused by
    a sandbox (a container's seccomp profile)."""
    try:
        os.close(os.pidfd_open(os.getpid()))
    except (AttributeError, OSError):
        return False
    return True


class _Forked:
    """The process of a twin (``_Worker(twin=True)``): forked by a worker, so not a child of
    this process, with the two calls ``_Worker`` makes of a ``subprocess.Popen``. Its id comes
    in its ready message (``found``), and a pidfd then holds it: the signal and the wait reach
    this very process even once it is gone and its id taken by another. Before that it is not
    killed: its stream closed, it exits as soon as it reads (it runs no task before it is
    ready)."""

    def __init__(self):
        self.pid: int | None = None
        self._handle: int | None = None  # None too once the process is gone (``wait``)

    def found(self, pid) -> None:
        self.pid = int(pid)
        try:
            self._handle = os.pidfd_open(self.pid)
        except OSError:  # gone already
            self._handle = None

    def kill(self) -> None:
        import signal

        if self._handle is not None:
            try:
                signal.pidfd_send_signal(self._handle, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def wait(self, timeout: float | None = None) -> None:
        import select
        import subprocess

        if self._handle is None:
            return
        poller = select.poll()
        poller.register(self._handle, select.POLLIN)  # readable once the process has exited
        if not poller.poll(None if timeout is None else max(0, int(timeout * 1000))):
            raise subprocess.TimeoutExpired("a meshcheck worker's twin", timeout)
        os.close(self._handle)
        self._handle = None


class LocalPool(Executor):
    """Tasks over ``jobs`` local worker processes, started on first need and kept for the run.

    Parameters
    ----------
    jobs : int, optional
        Worker processes at most; default all cores.

    Examples
    --------
    >>> with LocalPool(2) as pool:
    ...     pool.map("meshcheck.execute:echo", [Task((k,)) for k in range(5)])
    [0, 1, 2, 3, 4]
    """

    #: Workers that die before saying they are ready: after this many, give up (a broken
    #: environment would otherwise start workers forever).
    MAX_FAILED_STARTS = 3

    def __init__(self, jobs: int | None = None):
        self.jobs = int(jobs or default_jobs())
        self.workers: list[_Worker] = []
        #: Started workers kept out of ``workers`` (an early worker's twin): one joins a map
        #: that wants more workers than are in it, in place of a new one. A map this process
        #: takes tasks in leaves them out, so no more than ``jobs`` processes run its tasks.
        self.reserve: list[_Worker] = []
        self.failed_starts = 0

    @property
    def is_started(self) -> bool:
        return bool(self.workers)

    def prepare(self, function: str) -> None:
        # One worker fewer than jobs: a map that lets this process help wants no more. A worker
        # started early with the same function (``start_early``) joins when its task is taken.
        if not self.workers:
            early = sum(w.prepare == function for w in _EARLY.values())
            self.workers = [_Worker(function) for _ in range(self.jobs - 1 - early)]
            self.prepared = frozenset({function})

    def adopt(self, worker: _Worker) -> bool:
        """Take ``worker`` (ready and idle: an early one whose task was taken, ``take_early``)
        as one of the pool's, when the pool has room for it (one worker fewer than ``jobs``:
        this process takes tasks too), and its twin, if any, into ``reserve``; a twin sent more
        imports to make (``prepare_twin_early``) takes the worker's place, and the worker waits
        in ``reserve``. False when it has no room."""
        if len(self.workers) >= self.jobs - 1:
            return False
        called = frozenset({worker.prepare} - {None})
        self.prepared = called if not self.workers else self.prepared & called
        twin, worker.twin = worker.twin, None
        if twin is not None and twin.more_prepared:  # it serves; its worker waits in reserve
            worker, twin = twin, worker
        self.workers.append(worker)
        if twin is not None:
            self.reserve.append(twin)
        return True

    def another(self) -> _Worker:
        """A worker for ``workers``: from the reserve, or a new one."""
        return self.reserve.pop(0) if self.reserve else _Worker()

    @property
    def started(self) -> int:
        """Worker processes started, the reserve's too."""
        return len(self.workers) + len(self.reserve)

    #: Index of the task this process runs itself (``map(here=True)``), None otherwise.
    here_task: int | None = None

    @property
    def running(self) -> tuple[int, ...]:
        tasks = [w.task for w in list(self.workers) if w.task is not None]
        return tuple(sorted(tasks + ([] if self.here_task is None else [self.here_task])))

    def map(
        self, function, tasks, *, shared=None, progress=None, time_limit=None, here=False, grow=True
    ) -> list:
        source = None if isinstance(tasks, Sequence) else iter(tasks)
        tasks = [] if source is not None else list(tasks)
        if not tasks and source is None:
            return []
        # This process helps only where it cannot be asked to stop (no time limits) and the
        # workers already started leave a core to it. An iterator's tasks, not known yet, are
        # refused a time limit of their own there (``_LocalRun.add``).
        here = (
            here
            and time_limit is None
            and all(t.time_limit is None for t in tasks)
            and len(self.workers) < self.jobs
        )
        wanted = min(
            self.jobs - 1 if here else self.jobs, len(tasks) if source is None else self.jobs
        )
        if not grow:
            wanted = min(wanted, max(self.started, 0 if here else 1))
        while len(self.workers) < wanted:
            self.workers.append(self.another())
        shared = {} if shared is None else shared  # the iterator's to fill: the same dict
        run = _LocalRun(self, function, tasks, shared, progress, time_limit, wanted, here, source)
        try:
            return run.results_when_done()
        except BaseException:
            self.close()  # workers in the middle of a task cannot be reused
            raise

    def replace_lost(self, worker: _Worker) -> None:
        """Kill a worker that died or overran and take it out of the pool; give up when
        workers keep dying before they start."""
        worker.kill()
        self.workers.remove(worker)
        self.prepared = frozenset()  # its replacement calls no prepare function
        if not worker.is_ready:
            self.failed_starts += 1
            if self.failed_starts >= self.MAX_FAILED_STARTS:
                raise ExecutionError(
                    sys.executable,
                    "worker processes exit before they start (python -m meshcheck._worker); "
                    "run with -j 1 to check in this process",
                )

    def close(self) -> None:
        # Twins first: the workers that forked them, still running, reap them.
        for worker in sorted(self.reserve + self.workers, key=lambda w: not w.is_twin):
            if worker.task is None and (worker.is_ready or worker in self.reserve):
                worker.stop()  # a twin in reserve is idle: it says it is ready, then reads
            else:  # busy, or still starting (a prepared worker importing for a run that
                worker.kill()  # needed none of it: a warm run)
        self.workers, self.reserve = [], []
        self.prepared = frozenset()


# ---------------------------------------------------------------------------------------------
# Workers started before the run's pool


#: Workers started before a pool (``start_early``), each running one task, by its caller's key.
_EARLY: dict[object, _Worker] = {}


def start_early(
    key, function: str, args: tuple, *, prepare: str | None = None, twin: bool = False
) -> None:
    """Start a worker now, before the run's pool exists: it calls ``prepare`` (imports), then
    ``function(store, *args)``, while this process goes on. ``take_early(key)`` waits for the
    result; the worker then joins the run's pool, with its twin (``twin``: forked once
    ``prepare`` is done) in the pool's reserve.

    Examples
    --------
    >>> start_early("example", "meshcheck.execute:echo", (7,))
    >>> take_early("example")
    7
    """
    stop_early(key)
    worker = _SPARE.pop((prepare, twin), None) or _Worker(prepare, twin=twin)
    stop_spare()  # one left, started for another task: not wanted
    worker.send(("run", function, (), args))
    _EARLY[key] = worker


#: A worker started before the command knew its task (``start_spare``), by its ``prepare`` and
#: ``twin``.
_SPARE: dict[tuple[str | None, bool], _Worker] = {}


def start_spare(prepare: str | None = None, *, twin: bool = False) -> None:
    """Start a worker with no task yet: it calls ``prepare`` (imports) while this process reads
    its command line. The next ``start_early`` with the same ``prepare`` and ``twin`` gives it
    its task instead of starting a worker (0.1 s later, after the command line's imports); any
    other ``start_early``, or ``stop_spare``, stops it.

    Examples
    --------
    >>> start_spare()
    >>> start_early("example", "meshcheck.execute:echo", (8,))
    >>> take_early("example")
    8
    """
    stop_spare()
    _SPARE[(prepare, twin)] = _Worker(prepare, twin=twin)


def stop_spare() -> None:
    """Kill the spare worker (``start_spare``) no task was given to."""
    while _SPARE:
        _SPARE.popitem()[1].kill()


def take_early(key, pool: Executor | None = None):
    """The result of the task started under ``key`` (``start_early``), once it is done; None
    when none was started or its worker died. The worker then joins ``pool`` when that is a
    local pool with room for it (``LocalPool.adopt``), else stops.

    Raises
    ------
    RuntimeError
        The task raised (a bug): its traceback.
    """
    worker = _EARLY.pop(key, None)
    if worker is None:
        return None
    try:
        message = worker.receive_end.recv()
        if message[0] == "ready":
            worker.ready(message)
            message = worker.receive_end.recv()
    except (EOFError, OSError):
        worker.kill()
        return None
    if message[0] == "error":
        worker.kill()
        raise RuntimeError(f"a meshcheck worker failed:\n{message[1]}")
    if not (isinstance(pool, LocalPool) and pool.adopt(worker)):
        worker.stop()
    return message[1]


def prepare_twin_early(key, function: str) -> bool:
    """Have the twin of the worker started under ``key`` call ``function`` (imports its
    worker's task does not need) while that task runs, when it still runs: the twin then takes
    the worker's place in the pool (``LocalPool.adopt``). Whether it was sent."""
    worker = _EARLY.get(key)
    if worker is None or worker.twin is None:
        return False
    try:
        if not worker.is_ready and worker.receive_end.poll(0):
            worker.ready(worker.receive_end.recv())  # its first message says it is ready
        if worker.is_ready and worker.receive_end.poll(0):  # its result is in: too late
            return False
        worker.twin.send(("run", "meshcheck.execute:call_prepare", (), (function,)))
    except (EOFError, OSError):  # gone: ``take_early`` finds out
        return False
    worker.twin.preparing = worker.twin.more_prepared = True
    return True


def call_prepare(store: dict, function: str) -> None:
    """A task that calls a prepare function (``prepare_twin_early``); a failure is the later
    task's to meet, as a worker's failed prepare is (``_worker.main``)."""
    from ._process import imports_uncollected

    with contextlib.suppress(Exception), imports_uncollected():
        resolve(function)()


def has_early(key) -> bool:
    """Whether a worker started under ``key`` (``start_early``) has a result to take."""
    return key in _EARLY


def stop_early(key=None) -> None:
    """Kill the worker started early under ``key`` (default: every one) whose result was not
    taken: its task is not wanted any more."""
    for k in list(_EARLY) if key is None else [key]:
        worker = _EARLY.pop(k, None)
        if worker is not None:
            worker.kill()


class _LocalRun:
    """One ``LocalPool.map``: the tasks not started yet, the results, and the worker loop."""

    #: Seconds this process waits at most, before it runs a task, for its workers' tasks to be
    #: written to them (``written_to_workers``).
    WRITE_WAIT = 0.5

    def __init__(
        self, pool, function, tasks, shared, progress, time_limit, wanted, here=False, source=None
    ):
        self.pool, self.function, self.tasks, self.shared = pool, function, list(tasks), shared
        self.progress, self.time_limit, self.wanted = progress, time_limit, wanted
        self.results: list = [None] * len(tasks)
        self.pending = deque(sorted(range(len(tasks)), key=lambda i: -tasks[i].size))
        self.finished = 0
        self.here = here  # this process takes tasks too (``LocalPool.map``)
        self.store: dict | None = None  # its store, as a worker's
        #: The iterator the tasks are drawn from (``Executor.map``), None once it is drawn to
        #: its end: until then this process makes tasks and takes none.
        self.source: Iterator[Task] | None = source

    def results_when_done(self) -> list:
        from multiprocessing.connection import wait

        pool = self.pool
        for worker in list(pool.workers):  # idle workers kept from an earlier map
            if worker.is_ready and worker.task is None and self.pending:
                self.start(worker)
        while self.source is not None or self.finished < len(self.tasks):
            drawing = self.source is not None
            if drawing:
                self.draw()
            helps = drawing or (self.here and self.pending)
            if self.here and not self.pending and not drawing:
                self.take_back()
            for worker in wait(list(pool.workers), timeout=0.0 if helps else self.wait_timeout()):
                self.receive(worker)
            if drawing:  # the task just made goes to an idle worker now
                for worker in list(pool.workers):
                    if worker.is_ready and worker.task is None and self.pending:
                        self.start(worker)
            elif self.here and self.pending:
                self.run_here()
            now = time.monotonic()
            for worker in list(pool.workers):
                if worker.task is not None and now - worker.started > self.limit_of(worker.task):
                    self.lost(worker)
            if not pool.workers and self.pending and not drawing:
                pool.workers.append(pool.another())
        return self.results

    def draw(self) -> None:
        """Make the iterator's next task (``source``), or note its end."""
        task = next(self.source, None)
        if task is None:
            self.source = None
        else:
            self.add(task)

    def add(self, task: Task) -> None:
        """Take a task made while the map runs: pending, in its place by size (the largest
        first, in the order made among equal sizes)."""
        if self.here and task.time_limit is not None:
            raise ValueError("a task drawn from an iterator has no time limit of its own")
        index = len(self.tasks)
        self.tasks.append(task)
        self.results.append(None)
        position = len(self.pending)
        while position and self.tasks[self.pending[position - 1]].size < task.size:
            position -= 1
        self.pending.insert(position, index)

    def run_here(self) -> None:
        """Run a pending task in this process: first the largest the workers left (they
        started on the largest), so the two largest run side by side, not one after the other
        in a worker; then the smallest, the workers taking the largest.

        This process reads no message while it runs a task, so each busy worker is sent its
        next tasks as well, with the shared values they need: one at least, and as many as
        this one is large (``Task.size``) in all. It starts each as soon as it finishes the one
        before, instead of waiting idle for this one (which may be as long as its own when
        every task is large, and as long as several of its own when this one is the largest).
        A worker reads its messages as they come, while it runs a task
        (``_worker._Messages``), so a large value does not block this process. Once this
        process has no task left, it takes back the last next task not started, one at a
        time (``take_back``).
        """
        first = self.store is None  # made for the first task here, below
        index = self.pending.popleft() if first else self.pending.pop()
        task = self.tasks[index]
        for worker in list(self.pool.workers):  # a next task at least, as large as this one
            while self._queue_short(worker, task) and self.start(worker, queued=True):
                pass
        if self.store is None:
            self.store = dict(self.shared)
        self.written_to_workers()
        self.pool.here_task = index
        try:
            self.results[index] = call(self.function, self.store, task.needs, task.args)
        finally:
            self.pool.here_task = None
        self.count_finished()

    def _queue_short(self, worker: _Worker, task: Task) -> bool:
        """Whether busy ``worker`` has no task sent to run after its own, or fewer than ``task``
        is large (``Task.size``), and one is pending: it would wait idle for this process to
        run ``task``. Not while it is asked to give one back (``take_back``): it drops the last
        one it was sent, which must be the one asked for."""
        if worker.task is None or worker.withdrawing is not None or not self.pending:
            return False
        return not worker.queued or sum(self.tasks[i].size for i, *_ in worker.queued) < task.size

    def written_to_workers(self) -> None:
        """Wait until each ready worker's task is written to it (its shared values too), before
        this process runs one: its writing thread runs only when this process lets Python run,
        which a task inside one long OpenCASCADE call (a mesh, a boolean) does not until the
        call returns, and the worker would wait idle for it (for a product's text, say). A
        worker that is ready reads its messages as they come; one still importing is not
        waited for, nor any worker past ``WRITE_WAIT`` seconds in all.

        A busy worker's next tasks are waited for too when their messages fit in its pipe with
        ``PIPE_SPARE`` bytes to spare (``_Worker.pipe_bytes``): it reads nothing while its own
        task holds Python's lock, so only what the pipe holds is written meanwhile, and a next
        task not written in full would keep it waiting once its own is done."""
        deadline = time.monotonic() + self.WRITE_WAIT
        for worker in self.pool.workers:
            if worker.task is not None and worker.is_ready:
                count = worker.task_sent
                if (
                    worker.queued
                    and worker.bytes_sent - worker.task_bytes <= worker.pipe_bytes - PIPE_SPARE
                ):
                    count = worker.sent
                left = deadline - time.monotonic()
                if left <= 0.0 or not worker.wait_written(count, left):
                    return

    def take_back(self) -> None:
        """Ask each busy worker for the last task sent to run after its own (``run_here``), which
        this process, with no task left, can start now instead of once the worker's is done:
        the run ends no later, and sooner by as much as the worker's task has left to run. The
        worker gives it back only if it has not started it (``receive``)."""
        for worker in self.pool.workers:
            if not worker.queued or worker.withdrawing is not None:
                continue
            try:
                worker.send(("withdraw",))
            except (BrokenPipeError, OSError):  # gone: its stream's end says so
                continue
            worker.withdrawing = worker.queued[-1][0]  # the last sent: it drops the last

    def limit_of(self, index: int) -> float:
        task_limit = self.tasks[index].time_limit
        limit = task_limit if task_limit is not None else self.time_limit
        return math.inf if limit is None else limit

    def wait_timeout(self) -> float | None:
        """Seconds until the first running task's time limit, None without limits."""
        ends = [w.started + self.limit_of(w.task) for w in self.pool.workers if w.task is not None]
        ends = [end for end in ends if end < math.inf]
        return max(0.0, min(ends) - time.monotonic()) if ends else None

    def count_finished(self) -> None:
        self.finished += 1
        if self.progress is not None:
            self.progress(self.finished)

    def receive(self, worker: _Worker) -> None:
        """Take a worker's message (ready, a result, or its death) and give it the next task."""
        try:
            message = worker.receive_end.recv()
        except (EOFError, OSError):
            self.lost(worker)
            return
        if message[0] == "error":
            raise RuntimeError(f"a meshcheck worker failed:\n{message[1]}")
        if message[0] == "ready":
            worker.ready(message)
        elif message[0] == "ok" and worker.preparing:  # the imports it was sent first (its
            worker.preparing = False  # ``prepare_twin_early``) are made
        elif message[0] == "withdrawn":
            self.withdrawn(worker, message[1])
        else:
            self.results[worker.task] = message[1]
            self.count_finished()
            worker.task = None
        if worker.task is not None:
            return
        if worker.queued:  # already sent: it runs now (unless it is given back)
            worker.task, worker.task_sent, worker.task_bytes = worker.queued.popleft()
            worker.started = time.monotonic()
        elif self.pending:
            self.start(worker)

    def withdrawn(self, worker: _Worker, given_back: bool) -> None:
        """The worker's answer to ``take_back``: the task asked back is pending again when it
        gives it back (it had not started it, whether or not its result for the task before
        came first), and stays its own when it does not."""
        index, worker.withdrawing = worker.withdrawing, None
        if not given_back or index is None:
            return
        if worker.queued and worker.queued[-1][0] == index:
            worker.queued.pop()
        elif worker.task == index and not worker.queued:  # taken as started when the result
            worker.task = None  # before it came
        else:
            return
        self.pending.append(index)  # the smallest end: this process takes it next

    def lost(self, worker: _Worker) -> None:
        while worker.queued:  # sent, never started: another process takes them
            self.pending.appendleft(worker.queued.pop()[0])
        self.pool.replace_lost(worker)
        if worker.task is not None:
            self.count_finished()  # results[task] stays None: the caller decides what it means
        if self.pending and len(self.pool.workers) < self.wanted:
            self.pool.workers.append(self.pool.another())

    def start(self, worker: _Worker, *, queued: bool = False, index: int | None = None) -> bool:
        """Send ``worker`` the largest pending task (or the pending task ``index``): to run now,
        or ``queued`` after the one it runs. False when the worker is gone (``lost``)."""
        if index is None:
            index = self.pending.popleft()
        else:
            self.pending.remove(index)
        task = self.tasks[index]
        try:
            for key in task.needs:
                if key not in worker.keys:
                    worker.send(("put", key, self.shared[key]))
                    worker.keys.add(key)
            worker.send(("run", self.function, task.needs, task.args))
        except (BrokenPipeError, OSError):  # it died before taking the task: put it back
            self.pending.appendleft(index)
            if not queued:
                worker.task = None
            self.lost(worker)
            return False
        if queued:
            worker.queued.append((index, worker.sent, worker.bytes_sent))
        else:
            worker.task, worker.started = index, time.monotonic()
            worker.task_sent, worker.task_bytes = worker.sent, worker.bytes_sent
        return True


class DaskExecutor(Executor):
    """Tasks on a Dask distributed cluster; each shared value is scattered once.

    Parameters
    ----------
    address : str
        The scheduler, e.g. ``tcp://10.0.0.5:8786``.
    connect_timeout : float
        Seconds to wait for the scheduler before giving up.

    Raises
    ------
    ExecutionError
        Dask is not installed, or the scheduler cannot be reached.
    """

    is_distributed = True
    #: A task whose worker died is resubmitted this many times before the run gives up.
    ATTEMPTS = 3
    #: Seconds the cluster may have no worker at all before the run gives up.
    NO_WORKER_GRACE = 30.0

    def __init__(self, address: str, *, connect_timeout: float = 10.0):
        self.address = address
        _probe(address, connect_timeout)
        try:
            from distributed import Client
        except ImportError:
            raise ExecutionError(
                address, 'running on a cluster needs Dask: pip install "meshcheck-assembly[dask]"'
            ) from None
        _identify(address, connect_timeout)
        try:
            self.client = Client(address, timeout=connect_timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ExecutionError(address, f"cannot reach the Dask scheduler ({exc})") from None
        workers = self.client.scheduler_info().get("workers", {})
        self.jobs = max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))
        self._scattered: dict = {}  # key -> future of a shared value on the cluster
        self.sent_bytes = 0  # pickled bytes of the shared values scattered (bench/dask.py)
        self.task_count = 0

    def map(
        self, function, tasks, *, shared=None, progress=None, time_limit=None, here=False, grow=True
    ) -> list:
        """See ``Executor.map``; ``time_limit`` is not enforced on a cluster (a Dask worker
        cannot be killed per task): a CoACD overrun only takes longer there; ``here`` and
        ``grow`` are ignored (the cluster's workers do the work); an iterator of tasks is drawn
        to its end first."""
        tasks = list(tasks)
        if not tasks:
            return []
        run = _DaskRun(self, function, tasks, shared or {}, progress)
        try:
            return run.results_when_done()
        except (OSError, TimeoutError) as exc:
            raise ExecutionError(self.address, f"lost the Dask scheduler ({exc})") from None
        finally:
            for future in run.running:
                future.cancel()

    def _is_healthy(self) -> bool:
        """The client is connected and the cluster has at least one worker."""
        if self.client.status != "running":
            return False
        try:
            return bool(self.client.scheduler_info().get("workers"))
        except Exception:  # the scheduler is gone or does not answer
            return False

    def _submit(self, function: str, task: Task, shared: dict):
        import pickle

        needed = {}
        for key in task.needs:
            if key not in self._scattered:
                value = shared[key]
                self.sent_bytes += len(pickle.dumps(value, protocol=5))
                self._scattered[key] = self._scatter(value)
            needed[key] = self._scattered[key]
        self.task_count += 1
        return self.client.submit(_dask_call, function, needed, task.args, pure=False)

    def _scatter(self, value):
        """A future of ``value`` on the cluster. A worker that died a moment ago can still be
        chosen to hold it (the scheduler has not noticed yet): then wait and try again."""
        for attempt in range(self.ATTEMPTS):
            try:
                # in a list, so a tuple value travels as one piece, not one per element
                return self.client.scatter([value], hash=False)[0]
            except OSError:  # distributed's CommClosedError is one
                if attempt == self.ATTEMPTS - 1:
                    raise
                time.sleep(1.0)

    def close(self) -> None:
        client, self.client = getattr(self, "client", None), None
        self._scattered = {}
        if client is not None:
            import contextlib

            with contextlib.suppress(Exception):
                client.close(timeout=5)


class _DaskRun:
    """One ``DaskExecutor.map``: the futures running, their attempts, and the wait loop."""

    def __init__(self, executor, function, tasks, shared, progress):
        self.executor, self.function, self.tasks = executor, function, tasks
        self.shared, self.progress = shared, progress
        self.results: list = [None] * len(tasks)
        self.attempts = [0] * len(tasks)
        self.running: dict = {}  # future -> task index
        self.finished = 0

    def results_when_done(self) -> list:
        executor = self.executor
        for index in sorted(range(len(self.tasks)), key=lambda i: -self.tasks[i].size):
            self.submit(index)
        healthy_at = time.monotonic()
        while self.running:
            if self.collect(self.wait_a_second()):
                healthy_at = time.monotonic()
                continue
            # Nothing finished for a second: is anything still able to finish?
            self.resubmit_orphans()
            if executor._is_healthy():
                healthy_at = time.monotonic()
            elif time.monotonic() - healthy_at > executor.NO_WORKER_GRACE:
                raise ExecutionError(
                    executor.address,
                    f"no scheduler or no worker for {executor.NO_WORKER_GRACE:g} s; giving up",
                )
        return self.results

    def submit(self, index: int) -> None:
        future = self.executor._submit(self.function, self.tasks[index], self.shared)
        self.running[future] = index

    def wait_a_second(self) -> set:
        """The futures that finished (or were cancelled) within a second."""
        from distributed import wait

        try:
            from distributed.client import FuturesCancelledError
        except ImportError:  # older distributed: wait raises the plain CancelledError
            from concurrent.futures import CancelledError as FuturesCancelledError
        try:
            with self.executor.client.as_current():
                done, _ = wait(list(self.running), timeout=1.0, return_when="FIRST_COMPLETED")
        except TimeoutError:
            return set()
        except FuturesCancelledError:
            # The scheduler forgot a task whose input died with a killed worker: sent again
            # (``again``), as any lost task.
            return {f for f in self.running if f.cancelled()}
        return set(done)

    def collect(self, done: set) -> bool:
        """Store the results of ``done``, send the lost ones again; True if any was done."""
        for future in done:
            index = self.running.pop(future)
            if future.status != "finished":
                self.again(index, _describe(future))
                continue
            kind, value = future.result()
            if kind == "error":
                raise RuntimeError(f"a meshcheck task failed on the cluster:\n{value}")
            self.results[index] = value
            self.finished += 1
            if self.progress is not None:
                self.progress(self.finished)
        return bool(done)

    def resubmit_orphans(self) -> None:
        """Send again the tasks a value they need died for, with its only worker."""
        scattered = self.executor._scattered
        lost = [
            f
            for f, i in self.running.items()
            if any(
                scattered.get(k) is None or scattered[k].status != "finished"
                for k in self.tasks[i].needs
            )
        ]
        for future in lost:
            future.cancel()
            self.again(self.running.pop(future), "a mesh it needs was lost with a worker")

    def again(self, index: int, why: str) -> None:
        """Send a task again (its worker or a value it needs was lost), or give up."""
        executor = self.executor
        self.attempts[index] += 1
        if self.attempts[index] >= executor.ATTEMPTS:
            raise ExecutionError(
                executor.address,
                f"a task was lost {executor.ATTEMPTS} times on the cluster ({why}); "
                "workers keep dying?",
            )
        for key in self.tasks[index].needs:
            old = executor._scattered.get(key)
            if old is not None and old.status != "finished":
                del executor._scattered[key]
        self.submit(index)


def _dask_call(function: str, needed: dict, args: tuple):
    """Run one task on a Dask worker; a bug comes back as text, not as a lost task."""
    try:
        return ("ok", call(function, dict(needed), tuple(needed), args))
    except Exception:
        import traceback

        return ("error", traceback.format_exc())


def _describe(future) -> str:
    try:
        exc = future.exception(timeout=1)
    except Exception as err:  # the future itself is gone
        exc = err
    return f"{type(exc).__name__}: {exc}"[:200]


def _probe(address: str, timeout: float) -> None:
    """Fail at once, with one line, when nothing listens at a tcp:// scheduler address."""
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls"):
        return  # inproc:// and others: left to Dask
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        raise ExecutionError(address, "not a scheduler address (tcp://HOST:PORT)") from None
    if not host or port is None:
        raise ExecutionError(address, "not a scheduler address (tcp://HOST:PORT)")
    try:
        socket.create_connection((host, port), timeout=min(timeout, 5.0)).close()
    except OSError as exc:
        raise ExecutionError(
            address, f"cannot reach the Dask scheduler ({exc.strerror or exc})"
        ) from None


def _identify(address: str, timeout: float) -> None:
    """Fail within ``timeout`` seconds, with one line, unless a Dask scheduler answers at
    ``address``: something that accepts and never answers, sends garbage or announces a frame of
    2^62 bytes is refused here, before a ``Client`` (whose waits are not all bounded) is made."""
    import asyncio

    async def ask() -> object:
        from distributed.comm import connect

        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout))
    except TimeoutError:
        raise ExecutionError(
            address, f"no answer from the Dask scheduler within {timeout:g} s"
        ) from None
    except MemoryError:
        raise ExecutionError(
            address, "not a Dask scheduler (it announced a huge message)"
        ) from None
    except Exception as exc:  # garbage on the wire surfaces as any exception
        raise ExecutionError(
            address, f"not a Dask scheduler ({type(exc).__name__}: {str(exc)[:120]})"
        ) from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ExecutionError(address, "not a Dask scheduler (its answer is not a scheduler's)")


def executor_for(*, jobs: int | None = None, scheduler: str | None = None) -> Executor:
    """The executor a run uses: a Dask cluster when ``scheduler`` is given, else local processes
    (``jobs``, default all cores), else this process alone for ``jobs=1``."""
    if scheduler:
        return DaskExecutor(scheduler)
    jobs = local_jobs(jobs)
    return Executor() if jobs <= 1 else LocalPool(jobs)


def local_jobs(jobs: int | None = None) -> int:
    """The local processes a run given ``jobs`` (default all cores) uses, this one included."""
    return min(jobs or default_jobs(), max_local_jobs())


#: Memory a local worker is counted to need (its interpreter, numpy, trimesh, CoACD and one
#: task's meshes): ``-j`` never starts more workers than the available memory holds of these.
WORKER_BYTES = 256 << 20


#: Address space a check needs beyond the command's start-up (under ``ulimit -v``, the
#: command refuses to start with less): scipy's, trimesh's and the stages' imports map ~180 MiB,
#: and scipy's OpenBLAS loops for ever in its initialisation when it cannot map its buffers.
RUN_ADDRESS_SPACE = 320 << 20


def address_space_left() -> int | None:
    """Bytes this process may still map under its address-space limit (``ulimit -v``,
    ``RLIMIT_AS``); None when there is no limit or it cannot be read (outside Linux)."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/status", "rb") as fh:
            for line in fh:
                if line.startswith(b"VmSize:"):
                    return max(0, soft - int(line.split()[1]) * 1024)
    except (ImportError, OSError, ValueError, IndexError):
        pass
    return None


def max_local_jobs() -> int:
    """Local workers a run may start: no more than the cores this process may run on, nor than
    the available memory holds ``WORKER_BYTES`` (``-j 10000`` starts what the machine can run).
    """
    available = None
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    available = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    by_memory = default_jobs() if available is None else max(1, available // WORKER_BYTES)
    return max(1, min(default_jobs(), by_memory))
