"""Errors and warnings meshcheck raises on purpose.

A user mistake (a missing file, a broken mesh, a bad option) is a ``MeshcheckError`` subclass: the
command line prints it as one line, ``error: PATH: reason``, with no traceback. Anything else that
escapes is a bug: the command line exits with ``ExitStatus.INTERNAL`` and writes the traceback to
a file it names (or to stderr when ``MESHCHECK_DEBUG`` is set).
"""

from __future__ import annotations

import enum
import errno


class ExitStatus(enum.IntEnum):
    """Process exit codes of the ``meshcheck`` command, the one place they are defined."""

    OK = 0
    FAILED = 1  # a finding fails the run (interference, or what --fail-on selects)
    USAGE = 2  # bad options or arguments (click's own code for usage errors)
    INPUT = 3  # an input cannot be checked
    INTERNAL = 4  # a bug in meshcheck: one line on stderr says where the traceback is
    OUTPUT = 5  # a report or the export could not be written (disk full, device error...)
    RESOURCES = 6  # the machine ran out of memory, disk space or open files during the check


class MeshcheckError(Exception):
    """Base class of every error meshcheck reports to the user as one line."""

    exit_status = ExitStatus.INPUT

    def __init__(self, path: str | None, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)


class InputError(MeshcheckError):
    """An input file or directory cannot be read as a solid or surface mesh."""


class ConfigError(MeshcheckError):
    """A configuration file or option value is invalid."""

    exit_status = ExitStatus.USAGE


class OutputError(MeshcheckError):
    """A report or the export cannot be written once the check has run."""

    exit_status = ExitStatus.OUTPUT


class ResourceError(MeshcheckError):
    """The machine ran out of something the check needs (memory, disk space, open files): the
    inputs may be fine; the check did not happen (exit 6, never a pass, never a bug report)."""

    exit_status = ExitStatus.RESOURCES


#: OSError numbers that mean the machine ran out of something, and what ran out.
RESOURCE_ERRNOS = {
    errno.ENOMEM: "out of memory",
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EMFILE: "too many open files (the process's limit, ulimit -n)",
    errno.ENFILE: "too many open files (the system's limit)",
}

#: What a MemoryError (Python's, or std::bad_alloc in a compiled kernel) says to the user.
OUT_OF_MEMORY = "out of memory (the machine's, or a limit such as ulimit -v)"


def resource_error(exc: BaseException, path: str | None = None) -> ResourceError | None:
    """The ``ResourceError`` that ``exc`` stands for, or None when it is not exhaustion.

    Examples
    --------
    >>> resource_error(OSError(errno.EMFILE, "Too many open files"), "a.stl").reason
    "too many open files (the process's limit, ulimit -n)"
    >>> resource_error(MemoryError()).exit_status
    <ExitStatus.RESOURCES: 6>
    >>> resource_error(OSError(errno.ENOENT, "No such file")) is None
    True
    """
    if isinstance(exc, MemoryError):
        return ResourceError(path, OUT_OF_MEMORY)
    if isinstance(exc, OSError) and exc.errno in RESOURCE_ERRNOS:
        return ResourceError(path or exc.filename, RESOURCE_ERRNOS[exc.errno])
    return None


class MeshcheckWarning(UserWarning):
    """Something about an input deserves the user's attention but does not stop the check."""


class ExecutionError(MeshcheckError):
    """The work could not be run: a Dask scheduler that cannot be reached, workers that keep
    dying. The inputs may be fine; the check did not happen (exit 3, never a pass)."""
