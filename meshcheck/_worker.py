"""A local worker process: ``python -m meshcheck._worker``, started by ``execute.LocalPool``.

It is a fresh interpreter that imports meshcheck and nothing of the caller's, so a script without
an ``if __name__ == "__main__":`` guard, a notebook or ``python -c`` can call ``meshcheck.check``:
the caller's main module is never imported again. The worker talks to its parent over its
standard input and output (pickled messages between meshcheck's own processes, never files); C
code that prints (CoACD logs) writes to stderr instead, so it cannot garble the messages.

Messages from the parent::

    ("put", key, value)          keep ``value`` under ``key`` for later tasks
    ("run", function, needs, args)  call the named meshcheck function, reply with its result

Replies: ``("ready",)`` once at start, then ``("ok", result)`` or ``("error", text)`` per task.
The worker exits when its standard input closes (the parent finished or died).
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

    from meshcheck.execute import call

    store: dict = {}
    send.send(("ready",))
    while True:
        try:
            message = receive.recv()
        except (EOFError, OSError):
            return
        if message[0] == "put":
            store[message[1]] = message[2]
            continue
        _, function, needs, args = message
        try:
            reply = ("ok", call(function, store, needs, args))
        except Exception:  # a bug: its traceback goes back to the parent, which raises it
            import traceback

            reply = ("error", traceback.format_exc())
        try:
            send.send(reply)
        except (BrokenPipeError, OSError):
            return


if __name__ == "__main__":
    main()
