"""Output files (reports, the export): checked before any work, written without clobbering.

The rules, for every path meshcheck writes (``-o``, each ``--report``, ``--export``):

- ``-`` is standard output.
- A path that does not exist, or names a regular file, is written atomically: a temporary file in
  the same directory, then renamed over the path (an existing file keeps its permissions). A
  symbolic link to a regular file is written through, in place, and stays a link.
- A character device (``/dev/null``, ``/dev/full``, a terminal) is opened and written to; it is
  never renamed over.
- Anything else (a directory, a FIFO, a socket, a block device) is refused.

``check_output`` applies these rules before the check runs (a ``ConfigError``, exit status 2);
``write_output`` writes, and a failure there (a full disk, ``/dev/full``) is one ``OutputError``
naming the file (exit status 5).
"""

from __future__ import annotations

import os
import stat
import sys
import tempfile

from .errors import ConfigError, OutputError

STDOUT = "-"


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISBLK(mode):
        return "a block device"
    return "not a regular file"


def check_output(path: str, *, what: str = "report") -> None:
    """Refuse ``path`` unless meshcheck may write ``what`` there (see the module's rules).

    Raises
    ------
    ConfigError
        Naming the path and what is wrong: a missing or unwritable directory, or a target that
        is neither a regular file nor a character device.
    """
    if path == STDOUT:
        return
    if not path:
        raise ConfigError(None, f"the {what} path is empty")
    try:
        target = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise ConfigError(path, f"cannot write the {what}: a dangling symbolic link") from None
        target = None
    except OSError as exc:
        raise ConfigError(path, f"cannot write the {what} ({exc.strerror or exc})") from None
    if target is not None:
        if stat.S_ISCHR(target.st_mode):
            if not os.access(path, os.W_OK):
                raise ConfigError(path, f"cannot write the {what}: the device is not writable")
            return
        if not stat.S_ISREG(target.st_mode):
            raise ConfigError(
                path,
                f"cannot write the {what} there: it is {_kind(target.st_mode)} "
                "(meshcheck writes regular files, character devices such as /dev/null, or - "
                "for standard output)",
            )
        if os.path.islink(path):  # written through in place
            if not os.access(path, os.W_OK):
                raise ConfigError(path, f"cannot write the {what}: the file is not writable")
            return
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise ConfigError(path, f"cannot write the {what}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(path, f"cannot write the {what}: directory {parent} is not writable")


def write_output(path: str, data: str | bytes, *, what: str = "report") -> None:
    """Write ``data`` (str as UTF-8) to ``path`` by the module's rules.

    Raises
    ------
    OutputError
        The write failed (no space, a device error, the path changed into something meshcheck
        does not replace since it was checked).
    """
    payload = data.encode("utf-8") if isinstance(data, str) else data
    if path == STDOUT:
        write_stdout(payload, what=what)
        return
    try:
        try:
            current = os.stat(path)
        except FileNotFoundError:
            current = None
        if current is not None and not stat.S_ISREG(current.st_mode):
            if not stat.S_ISCHR(current.st_mode):
                raise OutputError(path, f"cannot write the {what}: it is {_kind(current.st_mode)}")
            _write_in_place(path, payload)
        elif current is not None and os.path.islink(path):
            _write_in_place(path, payload)
        else:
            _write_atomically(path, payload, None if current is None else current.st_mode)
    except OSError as exc:
        raise OutputError(path, f"cannot write the {what} ({exc.strerror or exc})") from None


def _write_in_place(path: str, payload: bytes) -> None:
    with open(path, "wb") as fh:  # close() flushes: ENOSPC surfaces here at the latest
        fh.write(payload)


def _write_atomically(path: str, payload: bytes, mode: int | None) -> None:
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{os.path.basename(path)}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(payload)
            fh.flush()
        # by name: os.fchmod is not on Windows before Python 3.13
        os.chmod(tmp, stat.S_IMODE(mode) if mode is not None else _new_file_mode())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _new_file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_stdout(data: str | bytes, *, what: str = "report") -> None:
    """Write to standard output and flush; a failure (a full disk, a closed pipe) is an
    ``OutputError`` and standard output is pointed at the null device, so the interpreter's
    final flush cannot fail again with a traceback."""
    payload = data.encode("utf-8") if isinstance(data, str) else data
    stream = sys.stdout
    try:
        buffer = getattr(stream, "buffer", None)
        if buffer is not None:
            stream.flush()
            buffer.write(payload)
            buffer.flush()
        else:  # a text-only stream (tests, embedding)
            stream.write(payload.decode("utf-8"))
            stream.flush()
    except OSError as exc:
        _silence_stdout()
        raise OutputError("<stdout>", f"cannot write the {what} ({exc.strerror or exc})") from None


def _silence_stdout() -> None:
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, AttributeError, ValueError):
        pass
