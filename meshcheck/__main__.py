"""The ``meshcheck`` command (the script, and ``python -m meshcheck``).

Its first step comes before the command line's modules are imported (numpy, click: 0.1 s on
a cold run): when the arguments name a STEP file and the run may use a second local process, a
worker starts importing OpenCASCADE at once (``execute.start_spare``), and the command gives it
the file to read once its options are read (``load.step.ahead``). The arguments are only
looked at, not parsed: ``cli.main`` parses them, and stops the worker when the run turns out to
want none (a scheduler in the configuration file, a report path ending in ``.step``, a usage
error); the load stage stops it when the file's tessellation is in the cache.
"""

from __future__ import annotations

import os
import sys

from . import _process  # noqa: F401  (first: it sets the process up before numpy)


def main(prog_name: str = "meshcheck") -> None:
    execute = None
    try:
        from . import execute

        try:
            if reads_step_ahead(sys.argv[1:]):
                from .load.step import PREPARE

                execute.start_spare(PREPARE, twin=True)
        except OSError:  # no process or pipe to be had: the run goes on without it
            pass
        from .cli import main as command
    except KeyboardInterrupt:  # Ctrl-C before the command line can say so (``cli``)
        if execute is not None:
            execute.stop_spare()
        sys.stderr.write("error: interrupted\n")
        raise SystemExit(130) from None
    try:
        command(prog_name=prog_name)
    finally:
        execute.stop_spare()


def reads_step_ahead(arguments: list[str]) -> bool:
    """Whether a run with these arguments will likely read a STEP file ahead
    (``load.step.ahead.start``): one of them names a STEP file, the run may use a second local
    process (``-j``, default all cores), and no option asks for a scheduler or only a message
    (help, version). A guess: the configuration file can still name a scheduler, and an
    option's value can look like a file.

    Examples
    --------
    >>> reads_step_ahead(["tests/data/step/box_sides.STEP", "-j", "1"])
    False
    >>> reads_step_ahead(["--help", "tests/data/step/box_sides.STEP"])
    False
    """
    from .execute import local_jobs
    from .load.formats import STEP_EXTENSIONS

    if os.environ.get("MESHCHECK_SCHEDULER"):
        return False
    step, jobs = False, None
    words = iter(arguments)
    for word in words:
        if word == "--":  # the rest are files
            step = step or any(_names_step(w, STEP_EXTENSIONS) for w in words)
            break
        name, equals, value = word.partition("=")
        if name in ("-h", "--help", "--version", "--scheduler"):
            return False
        if name in ("-j", "--jobs"):
            jobs = value if equals else next(words, "")
        elif word.startswith("-j"):  # -j2
            jobs = word[2:]
        elif not word.startswith("-"):
            step = step or _names_step(word, STEP_EXTENSIONS)
    if jobs is not None:
        try:
            jobs = int(jobs)
        except ValueError:
            return False  # a usage error
        if jobs < 1:
            return False
    return step and local_jobs(jobs) >= 2


def _names_step(word: str, extensions: tuple[str, ...]) -> bool:
    return os.path.splitext(word)[1].lower() in extensions and os.path.isfile(word)


if __name__ == "__main__":
    main()
