"""A local worker process: ``python -m meshcheck._worker``, started by ``execute.LocalPool``.

It is a fresh interpreter that imports meshcheck and nothing of the caller's, so a script without
an ``if __name__ == "__main__":`` guard, a notebook or ``python -c`` can call ``meshcheck.check``:
the caller's main module is never imported again. The worker talks to its parent over its
standard input and output (pickled messages between meshcheck's own processes, never files); C
code that prints (CoACD logs) writes to stderr instead, so it cannot garble the messages.

Messages from the parent::

    ("put", key, value)          keep ``value`` under ``key`` for later tasks
    ("run", function, needs, args)  call the named meshcheck function, reply with its result
    ("withdraw",)                take back the last task sent to run after the one running,
                                 if it has not started: reply ``("withdrawn", True)``, or
                                 ``("withdrawn", False)`` when it has (or there is none)

Its first optional argument names a function (``module:name``) it calls first, before it says
it is ready: the imports its tasks will need, made while the parent loads the inputs. The second,
``READ,WRITE``, names two pipe ends the parent passed it for a second worker, its twin: once the
imports are made, and before it starts a thread, the worker forks, and the twin serves the
parent over those two pipes with the imports already made (OpenCASCADE: 0.6-0.8 s of CPU a
freshly started worker would spend again). The twin is not the parent's child: it names its
process id in its ready message; its worker reaps it as it leaves, once the parent has stopped
the twin first (``LocalPool.close``), so the twin's CPU time counts in the worker's children and
so in the parent's.

Replies: ``("ready", pid)`` once at start, then ``("ok", result)`` or ``("error", text)`` per
task, and ``("withdrawn", ...)`` per withdraw, in the order they are made. The worker exits
when its standard input closes (the parent finished or died).
"""

from __future__ import annotations

import os
import sys


def main() -> None:
    """Serve tasks over the standard streams until the parent closes them."""
    from multiprocessing.connection import Connection

    receive = Connection(os.dup(0), writable=False)
    send = Connection(os.dup(1), readable=False)
    # Anything printed from here on (Python or C) goes to stderr, not into the message stream.
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    sys.stdout = sys.stderr

    from meshcheck._process import imports_uncollected  # and the command's process settings
    from meshcheck.execute import Writer, call, resolve

    if len(sys.argv) > 1:  # the parent's prepare function (Executor.prepare): imports
        try:
            with imports_uncollected():
                resolve(sys.argv[1])()
        except Exception:  # no traceback on the user's terminal: the parent starts a worker
            _leave(1)  # without it, and meets the failure itself if a task needs that import
    if len(sys.argv) > 2:  # the twin's pipes: fork it now, while this is the only thread
        receive, send = _fork_twin(receive, send, sys.argv[2])
    replies = Writer(send)
    replies.put(("ready", os.getpid()))
    messages = _Messages(receive, replies)
    store: dict = {}
    while True:
        message = messages.get()
        if message is None:  # the parent closed the stream, or is gone
            replies.close()
            _leave()
        if message[0] == "put":
            store[message[1]] = message[2]
            continue
        _, function, needs, args = message
        try:
            reply = ("ok", call(function, store, needs, args))
        except Exception:  # a bug: its traceback goes back to the parent, which raises it
            import traceback

            reply = ("error", traceback.format_exc())
        if not replies.put(reply):
            _leave()


def _fork_twin(receive, send, pipes: str) -> tuple:
    """Fork the twin; the connections this process serves: the twin's (the two pipe ends named
    by ``pipes``) in the twin, its own here. Each closes the other's ends, so either one's exit
    is the end of its stream for the parent. A failed fork leaves the twin's stream closed: the
    parent sees a worker that died before it was ready."""
    from multiprocessing.connection import Connection

    read, write = (int(end) for end in pipes.split(","))
    sys.stderr.flush()
    try:
        pid = os.fork()
    except OSError:
        pid = -1
    if pid == 0:
        receive.close()
        send.close()
        return Connection(read, writable=False), Connection(write, readable=False)
    os.close(read)
    os.close(write)
    return receive, send


def _leave(status: int = 0) -> None:
    """End the process now, without the interpreter's teardown: it holds nothing to save (every
    reply is written), and freeing what its tasks kept (OpenCASCADE's solids, meshes) one object
    at a time is time its parent waits for (``LocalPool.close``). Its twin, when it has exited
    (the parent stops twins first), is reaped first: its CPU time then counts in this process's
    children, which the parent reaps in turn (a benchmark's ``RUSAGE_CHILDREN``)."""
    sys.stderr.flush()
    try:
        while os.waitpid(-1, os.WNOHANG)[0]:
            pass
    except ChildProcessError:  # no child (left)
        pass
    os._exit(status)


class _Messages:
    """The parent's messages, read by a thread of their own as they come.

    The parent sends a busy worker its next task, with the shared values it needs, before it
    runs one of its own (``execute._LocalRun.run_here``), and reads no reply until that one is
    done: a value larger than the pipe's buffer, read only when this worker finished its task,
    would block the parent that long.

    The parent may take that next task back, to run it itself when it has none left
    (``execute._LocalRun.take_back``): this thread answers a withdraw itself, as soon as it runs
    (a task inside one long OpenCASCADE call lets it run only when the call returns)."""

    def __init__(self, connection, replies):
        import queue
        import threading

        self.connection, self.queue, self.replies = connection, queue.Queue(), replies
        threading.Thread(target=self._read, daemon=True).start()

    def get(self):
        """The next message, in order; None once the stream is closed."""
        return self.queue.get()

    def _read(self) -> None:
        while True:
            try:
                message = self.connection.recv()
            except (EOFError, OSError):
                self.queue.put(None)
                return
            if message[0] == "withdraw":
                self.replies.put(("withdrawn", self._withdraw()))
            else:
                self.queue.put(message)

    def _withdraw(self) -> bool:
        """Drop the task waiting to run, if the loop has not taken it: whether there was one."""
        with self.queue.mutex:
            waiting = self.queue.queue
            for i in range(len(waiting) - 1, -1, -1):
                if waiting[i] is not None and waiting[i][0] == "run":
                    del waiting[i]
                    return True
        return False


if __name__ == "__main__":
    main()
