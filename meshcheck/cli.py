"""The ``meshcheck`` command: parse options, call ``check``, render, exit. No geometry here.

Heavy modules (trimesh, scipy, CoACD) are imported inside ``main`` only, so ``--help`` and usage
errors stay quick.
"""

from __future__ import annotations

import contextlib
import gc
import os
import sys
import warnings

import click

from . import (
    DISTRIBUTION,
    _process,  # noqa: F401  (before the modules below: it sets the process up before numpy)
)
from .config import FAIL_ON_CHOICES, NUMBER_RANGES, checked_number, parse_fail_on
from .errors import (
    ConfigError,
    ExitStatus,
    MeshcheckError,
    MeshcheckWarning,
    OutputError,
    ResourceError,
    resource_error,
)
from .motion import MAX_SWEEP_BUDGET
from .outcome import exit_status
from .output import STDOUT, check_output, write_output
from .reports import FORMATS, printable, render, summary_line
from .units import METRES as UNITS

#: Set (to anything) to print an unexpected error's traceback on stderr instead of to a file.
DEBUG_ENV = "MESHCHECK_DEBUG"


class FiniteFloat(click.ParamType):
    """A float option that must be finite and in the range of its setting (NaN and inf refused)."""

    name = "float"

    def __init__(self, setting: str):
        self.setting = setting

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            return checked_number(f"--{self.setting}", value, *NUMBER_RANGES[self.setting])
        except ConfigError as exc:
            self.fail(exc.reason, param, ctx)


def _fail_on_option(ctx, param, values):
    """``--fail-on`` values (repeated or comma lists), checked; None when absent."""
    if not values:
        return None
    try:
        parse_fail_on(values)
    except ConfigError as exc:
        raise click.BadParameter(exc.reason) from None
    return values


def _report_option(ctx, param, values):
    """``--report FORMAT:PATH`` values as (format, path) pairs, checked."""
    pairs = []
    for value in values:
        fmt, sep, path = value.partition(":")
        if not sep or not path:
            raise click.BadParameter(f"{value!r} is not FORMAT:PATH (e.g. junit:meshcheck.xml)")
        if fmt not in FORMATS:
            raise click.BadParameter(f"unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
        pairs.append((fmt, path))
    return pairs


def _units(values) -> tuple[str | None, tuple]:
    """``--units`` values as (the unit of undeclared files and the report, or None; the
    ``FILE=UNIT`` rules), checked: one plain unit at most, every unit known.

    Raises
    ------
    ConfigError
        An unknown unit, a ``FILE=`` without a unit, two different plain units.
    """
    from .units import unit_name, unit_rule

    plain, rules = [], []
    for value in values:
        pattern = value.rpartition("=")[0]
        try:
            if "=" in value:
                rules.append(unit_rule(value))
            else:
                plain.append(unit_name(value))
        except ValueError as exc:
            raise ConfigError(pattern or None, f"--units: {exc}") from None
    if len(set(plain)) > 1:
        raise ConfigError("--units", f"give one report unit, not {' and '.join(plain)}")
    return (plain[0] if plain else None), tuple(rules)


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("files", nargs=-1, required=True)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(FORMATS),
    default="text",
    show_default=True,
    help="Report format for stdout (or -o): text (a table and a summary line), json, junit "
    "(XML), github (annotations), sarif (2.1.0, for code scanning), markdown (a step summary), "
    "html (one self-contained file with a 3D view of the clashes).",
)
@click.option(
    "--output",
    "-o",
    "output",
    default=None,
    metavar="PATH",
    help="Write the --format report to this file instead of stdout (the summary line goes to "
    "stderr).",
)
@click.option(
    "--report",
    "reports",
    multiple=True,
    callback=_report_option,
    metavar="FORMAT:PATH",
    help="Also write a report in FORMAT to PATH (- for stdout); repeatable, e.g. "
    "--report junit:meshcheck.xml --report sarif:meshcheck.sarif --report github:-.",
)
@click.option(
    "--quiet/--no-quiet",
    "-q",
    default=None,
    help="List only the findings that fail the run, then the summary (text and markdown). "
    "Default: the config file's quiet, else off.",
)
@click.option(
    "--hide-touching/--show-touching",
    default=None,
    help="Leave touching findings out of the table; the summary still counts them (text and "
    "markdown). Default: the config file's hide_touching, else shown.",
)
@click.option(
    "--baseline",
    "baseline_path",
    default=None,
    metavar="REPORT.json",
    help="A previous JSON report: mark each finding new or active and list the resolved ones.",
)
@click.option(
    "--clearance",
    type=FiniteFloat("clearance"),
    default=None,
    help="Also report part pairs closer than this distance (model units); they fail the run.",
)
@click.option(
    "--tolerance",
    type=FiniteFloat("tolerance"),
    default=None,
    help="Overlaps and gaps below this count as touching (model units). Default: each pair's "
    "own, 1e-5 of the smaller part's size (at least the float32 rounding of its coordinates).",
)
@click.option(
    "--threshold",
    type=FiniteFloat("threshold"),
    default=None,
    help="CoACD concavity threshold for the convex pieces. Default: 0.1.",
)
@click.option(
    "--fail-on",
    "fail_on",
    multiple=True,
    callback=_fail_on_option,
    metavar="STATUSES",
    help=f"Statuses that fail the run besides interference: comma list or repeated, from "
    f"{', '.join(FAIL_ON_CHOICES)}; or none alone (nothing fails); new fails only the findings "
    "of those statuses that --baseline does not hold. "
    "Default: interference, plus clearance when a clearance is set.",
)
@click.option(
    "--test",
    "tests",
    multiple=True,
    metavar="NAME:A:B[:KEY=VALUE]...",
    help="A clash test: the parts A names against those B names (comma lists of globs; * for "
    "every part), with its own clearance=, tolerance= and fail_on= (a comma list), e.g. "
    "--test 'fasteners:bolt_*:plate.stl:fail_on=interference'. Repeatable; replaces the config "
    "file's [[test]] tables; unset values are the run's. Each test is a section of the report, "
    "and the run fails when one of them does.",
)
@click.option(
    "--units",
    "units",
    multiple=True,
    metavar="UNIT|FILE=UNIT",
    help="UNIT: unit of mesh files that declare none (STL, OBJ, PLY, OFF), and of the report. "
    "Default: the unit every input declares, else mm. Files that declare a unit (glTF: metres, "
    "3MF, STEP) are converted; URDF robots are metres. FILE=UNIT (repeatable): the unit of the "
    "input files FILE names (a path, or a glob such as 'cad/*.glb'), whatever they declare, "
    "e.g. --units engine.glb=mm for a glTF exported in millimetres. "
    f"Units: {', '.join(UNITS)} (or their full names: millimetre, inch...).",
)
@click.option(
    "--step-deflection",
    type=FiniteFloat("step_deflection"),
    default=None,
    help="How far the triangles of STEP parts may lie from the CAD surface, in --units "
    "(default 0.005 mm). Overlaps and gaps within two parts' deflections count as touching.",
)
@click.option(
    "--max-triangles",
    type=click.IntRange(min=1),
    default=None,
    help="Refuse runs with more triangles than this, every placed instance counted "
    "(default 50 million): raise it for giant assemblies.",
)
@click.option(
    "--split",
    is_flag=True,
    help="Make each disconnected shell of a mesh its own part (NAME#1, NAME#2... in file order).",
)
@click.option(
    "--config",
    "config_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Read settings from this file instead of the meshcheck.toml or pyproject.toml "
    "[tool.meshcheck] found from the working directory upward.",
)
@click.option("--no-config", is_flag=True, help="Ignore configuration files.")
@click.option(
    "--cache-dir",
    type=click.Path(file_okay=False),
    default=None,
    help="Where decompositions, pair verdicts and STEP tessellations are kept. Default: the "
    "user's cache directory.",
)
@click.option("--no-cache", is_flag=True, help="Neither read nor write any cache.")
@click.option(
    "--jobs",
    "-j",
    type=click.IntRange(min=1),
    default=None,
    help="Local worker processes for decomposition and pair verification (small runs verify "
    "in this process). Default: all cores.",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="Run decomposition and pair verification on this Dask cluster (tcp://HOST:8786; "
    'needs pip install "meshcheck-assembly[dask]"). Default: $MESHCHECK_SCHEDULER, then the config '
    "file's scheduler; none runs locally.",
)
@click.option(
    "--export",
    "export_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write the assembly with clashes marked in red to this .glb or .gltf file.",
)
@click.option(
    "--pose",
    "pose",
    multiple=True,
    metavar="JOINT=VALUE,...",
    help="Joint values URDF robots are checked at: radians or metres, or degrees as 30deg "
    "(default zero); repeatable. Mimic joints follow their leader.",
)
@click.option(
    "--package-path",
    "package_paths",
    multiple=True,
    type=click.Path(file_okay=False),
    metavar="DIR",
    help="Also look for package:// meshes of URDF files here (besides the URDF's folder and its "
    "ancestors); repeatable.",
)
@click.option(
    "--adjacent/--no-adjacent",
    "adjacent",
    default=None,
    help="Approve findings between robot links joined by a joint (reason adjacent), as MoveIt "
    "does. Default: on.",
)
@click.option(
    "--sweep",
    is_flag=True,
    help="Classify every pair of robot links as never / sometimes / always in contact over the "
    "joint ranges; never is proven, sometimes comes with a witness pose. Parts of a [[joint]] "
    "mechanism that interfere in motion fail the run.",
)
@click.option(
    "--sweep-joints",
    default=None,
    metavar="JOINT,...",
    help="Sweep only these joints (the others stay at --pose). Implies --sweep.",
)
@click.option(
    "--sweep-budget",
    type=click.IntRange(min=1, max=MAX_SWEEP_BUDGET),
    default=None,
    metavar="N",
    help="Work the sweep may do: each pose of a link pair costs the joints that move it, each "
    "pair of convex pieces measured costs 1 (default 1,000 million; config key sweep_budget). "
    "Pairs left over are undecided, never proven apart.",
)
@click.option(
    "--srdf",
    "srdf_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write MoveIt disable_collisions entries (Adjacent, Never, Always) from the sweep to "
    "this SRDF file. Implies --sweep. With --audit-srdf: write the audited SRDF corrected (its "
    "entries that disable a collision removed, each with a comment giving its witness pose).",
)
@click.option(
    "--audit-srdf",
    "audit_path",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="SRDF",
    help="Audit this SRDF of the URDF robot: sweep each pair its disable_collisions entries "
    "disable (see --audit-reasons) over the joint ranges; a pair that collides at some pose "
    "fails the run, with its witness pose.",
)
@click.option(
    "--audit-reasons",
    "audit_reasons",
    default=None,
    metavar="REASONS",
    help="The disable_collisions reasons --audit-srdf audits: a comma list (Never,Default,User,"
    "Adjacent,Always...) or all. Default: Never.",
)
@click.option(
    "--allow-outside-paths",
    "allow_outside",
    is_flag=True,
    help="Read the files a URDF names even outside its folder, its package and --package-path "
    "folders (by default such a path is refused, exit 3: a robot from a pull request reads "
    "nothing else on the runner).",
)
@click.version_option(package_name=DISTRIBUTION)
def main(**options):
    """Check the parts in FILES for interference, contact and clearance.

    FILES are mesh files (STL, OBJ, PLY, OFF, GLB/GLTF, 3MF), STEP files (.step, .stp), URDF
    robots (.urdf) or directories (every such file below them). A part is named by its path as
    given; a body inside a file holding several is PATH#NODE, a robot's link ROBOT.urdf#LINK.

    Exit status: 0 when nothing fails, 1 when a finding fails the run (interference and
    duplicates by default, and clearance violations when --clearance is given), 2 for a usage
    or configuration error
    (output paths and the baseline are checked before any work), 3 when an input cannot be
    checked, 4 for a bug in meshcheck (the traceback goes to a file named on stderr, or to stderr
    when MESHCHECK_DEBUG is set), 5 when a report or the export cannot be written, 6 when the
    machine runs out of memory, disk space or open files.

    \b
    Examples:
      meshcheck assembly/ --clearance 0.2
      meshcheck gearbox.step --report html:clashes.html --report junit:meshcheck.xml
    """
    with _interrupts_noted() as pressed:
        try:
            _run(click.get_current_context(), **options)
        except KeyboardInterrupt:
            _interrupted()
        except click.exceptions.ClickException:
            raise
        except MeshcheckError as exc:
            _fail(exc)
        except Exception as exc:
            # Ctrl-C inside an extension's initialisation (an ImportError), or swallowed where
            # it was met (a library's optional import) and the half-made module failing since
            if pressed or _is_interrupt(exc):
                _interrupted()
            exhausted = resource_error(exc)
            if exhausted is None:
                _internal_error(exc)
            _fail(exhausted)


def _run(
    ctx,
    *,
    files,
    fmt,
    output,
    reports,
    baseline_path,
    export_path,
    srdf_path=None,
    audit_path=None,
    audit_reasons=None,
    allow_outside=False,
    pose=(),
    package_paths=(),
    adjacent=None,
    sweep=False,
    sweep_joints=None,
    sweep_budget=None,
    quiet=None,
    hide_touching=None,
    units=(),
    tests=(),
    **options,
):
    """Refuse what can be refused, check, write the reports, exit with the run's status."""
    try:
        targets = _targets(ctx, fmt, output, reports)
        _check_outputs(targets, export_path)
        if srdf_path is not None:
            check_output(srdf_path, what="SRDF")
        motion = {
            "pose": pose or None,
            "package_paths": package_paths,
            "adjacent": adjacent,
            "sweep": sweep_joints or ("" if sweep or (srdf_path and not audit_path) else None),
            "audit": audit_path,
            "audit_reasons": audit_reasons,
            "allow_outside": allow_outside,
            "budget": sweep_budget,
        }
        report_unit, file_units = _units(units)
        settings = _settings(
            motion=motion,
            units=report_unit,
            file_units=file_units,
            quiet=quiet,
            hide_touching=hide_touching,
            tests=tests or None,  # none given: the configuration's
            **options,
        )
        _refuse_robot_options(
            files,
            settings.motion,
            {
                "--pose": bool(pose),
                "--sweep": sweep,
                "--sweep-joints": sweep_joints is not None,
                "--srdf": srdf_path is not None,
                "--audit-srdf": audit_path is not None,
            },
        )
        inputs = [*files, baseline_path, settings.config_path, audit_path]
        outputs = [p for _, p in targets] + [export_path, srdf_path]
        _refuse_inputs_as_outputs(inputs, outputs)
        baseline = _baseline(baseline_path)
    except MeshcheckError as exc:
        _fail(exc)
    result = _check(files, settings, baseline, export_path)
    view_options = {
        "is_quiet": settings.quiet,
        "is_touching_listed": not settings.hide_touching,
    }
    written = _write_reports(result, targets, files, srdf_path, view_options)
    if written:
        noun = "report" if len(written) == 1 else "reports"
        where = ", ".join(printable(p) for p in written)
        click.echo(f"{summary_line(result)}; {noun} written to {where}", err=True)
    # The report is out. Freezing the heap spares the interpreter's exit-time collections a walk
    # over the ~135k objects numpy, scipy and trimesh created: 0.2 s of a 1.5 s warm run.
    gc.freeze()
    sys.exit(int(exit_status(result)))


def _refuse_robot_options(files, motion, given: dict[str, bool]) -> None:
    """A ConfigError, before any work, for a robot option with no robot to apply it to: a pose
    or a sweep needs a URDF robot among the inputs or the configuration's ``[[joint]]``
    mechanism; an SRDF (written or audited) describes one URDF robot."""
    robots = _robot_files(files)
    for option in ("--srdf", "--audit-srdf"):
        if given[option] and len(robots) != 1:
            held = "none"
            if robots:
                held = f"{len(robots)}: {', '.join(robots[:3])}" + (" ..." * (len(robots) > 3))
            raise ConfigError(option, f"an SRDF describes one URDF robot; the inputs hold {held}")
    if robots or motion.joints:
        return
    for option in ("--pose", "--sweep", "--sweep-joints"):
        if given[option]:
            raise ConfigError(
                option,
                "no input is a URDF robot and the configuration has no [[joint]] tables: "
                "nothing to pose or sweep",
            )


def _robot_files(files) -> list[str]:
    """The URDF files among the inputs, as the loader finds them (``load.paths.walk_meshes``:
    hidden entries of a directory skipped), without reading any."""
    from .load.formats import URDF_EXTENSIONS
    from .load.paths import walk_meshes

    out = []
    for path in files:
        if os.path.isdir(path):
            found = sorted(walk_meshes(path))
            out += [os.path.join(path, r) for r in found if r.lower().endswith(URDF_EXTENSIONS)]
        elif path.lower().endswith(URDF_EXTENSIONS):
            out.append(path)
    return out


def _check_outputs(targets, export_path) -> None:
    """Refuse report and export paths meshcheck may not write (``output.check_output``)."""
    for _, path in targets:
        check_output(path)
    if export_path is not None:
        from .reports.gltf import export_type

        export_type(export_path)


def _settings(*, config_path, no_config, no_cache, **options):
    """The run's ``Settings`` from the remaining options and the configuration file."""
    from .settings import Settings

    if no_config and config_path is None:
        config = None
    else:
        config = "auto" if config_path is None else config_path
    return Settings.from_options(config=config, use_cache=not no_cache, **options)


def _baseline(path):
    if path is None:
        return None
    from .baseline import load_baseline

    return load_baseline(path)


def _check(files, settings, baseline, export_path):
    """Run the check (and the export); print its warnings; exit on an error, after them."""
    from ._process import imports_uncollected
    from .execute import RUN_ADDRESS_SPACE, address_space_left, stop_spare
    from .progress import Progress

    left = address_space_left()
    if left is not None and left < RUN_ADDRESS_SPACE:
        raise ResourceError(
            None,
            f"out of memory: the address-space limit leaves {left >> 20} MiB after start-up, "
            f"a check needs {RUN_ADDRESS_SPACE >> 20} MiB",
        )
    ahead = _read_ahead(files, settings)  # a STEP file read while the pipeline is imported
    stop_spare()  # a worker the command started for a read it does not make (``__main__``)
    error = None
    try:
        with Progress("starting", 0), _interrupts_held(), imports_uncollected():
            from .pipeline import check  # numba, trimesh, scipy: seconds on a cold disk

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", MeshcheckWarning)
            try:
                result = check(files, settings)
                if baseline is not None:
                    from .outcome import compare

                    result = compare(result, baseline)
                if export_path is not None:
                    from .reports.gltf import export_clashes

                    export_clashes(export_path, result.bodies, result.findings, units=result.units)
            except MeshcheckError as exc:
                error = exc
    finally:
        if ahead is not None:
            ahead.stop()  # a file the run did not take (it failed first)
    for w in caught:
        if issubclass(w.category, MeshcheckWarning):
            click.echo(f"warning: {printable(str(w.message))}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    if error is not None:
        _fail(error)
    return result


def _read_ahead(files, settings):
    """Start reading the first STEP file among ``files`` in a worker (``load.step.ahead``); the
    module that did, None when there is no STEP file or it cannot even be imported (no file
    descriptor left: the run goes on without it, and says what it cannot open)."""
    from .load.formats import STEP_EXTENSIONS

    if not any(str(f).lower().endswith(STEP_EXTENSIONS) for f in files):
        return None
    try:
        from .load.step import ahead
    except OSError:
        return None
    ahead.start(files, settings)
    return ahead


def _write_reports(result, targets, files, srdf_path=None, view_options=None) -> list[str]:
    """Write every report; the files written when all of them went to files. A report that
    cannot be written is an error line and exit 5, after the others are written; then no summary
    line follows (stderr's last line is the error)."""
    failed = None
    for report_fmt, path in targets:
        try:
            from .reports import View
            from .reports.text import terminal_width

            width = terminal_width(is_terminal=path == STDOUT and sys.stdout.isatty())
            view = View(width=width, **(view_options or {}))
            write_output(path, render(result, report_fmt, inputs=files, view=view))
        except OutputError as exc:
            click.echo(f"error: {printable(str(exc))}", err=True)
            failed = exc

    for robot in result.sweeps:  # the sweep's counts, with or without --srdf
        click.echo(f"sweep: {printable(robot.summary())}", err=True)
    if result.audit is not None:
        click.echo(f"audit: {printable(result.audit.summary())}", err=True)
    if srdf_path is not None and _write_srdf(srdf_path, result):
        failed = True
    if failed is not None:
        sys.exit(int(ExitStatus.OUTPUT))
    if any(path == STDOUT for _, path in targets):
        return []
    return [path for _, path in targets]


def _write_srdf(path: str, result) -> bool:
    """Write the sweep's SRDF, or the audited SRDF corrected; True when it failed."""
    from .reports.srdf import corrected
    from .reports.srdf import render as render_srdf

    try:
        text = render_srdf(result) if result.audit is None else corrected(result)
    except MeshcheckError as exc:  # no robot, or several: a usage error
        _fail(exc)
    try:
        write_output(path, text, what="SRDF")
    except MeshcheckError as exc:
        click.echo(f"error: {printable(str(exc))}", err=True)
        return True
    return False


def _targets(ctx, fmt, output, reports) -> list[tuple[str, str]]:
    """(format, path) of every report to write; ``-`` is stdout, which carries one report only.

    ``--format`` goes to ``-o`` or stdout; it is left out when a ``--report FORMAT:-`` takes
    stdout and ``--format`` was not given.
    """
    targets = list(reports)
    explicit = ctx.get_parameter_source("fmt") is click.core.ParameterSource.COMMANDLINE
    if output is not None:
        if output == STDOUT:
            raise ConfigError(None, "-o - is standard output, where the report goes anyway")
        targets.insert(0, (fmt, output))
    elif explicit or all(path != STDOUT for _, path in reports):
        targets.insert(0, (fmt, STDOUT))
    seen = set()
    for _, path in targets:
        key = path if path == STDOUT else os.path.abspath(path)
        if key in seen:
            where = "standard output" if path == STDOUT else printable(path)
            raise ConfigError(None, f"two reports would be written to {where}")
        seen.add(key)
    return targets


def _refuse_inputs_as_outputs(inputs, outputs) -> None:
    """A ConfigError when an output would be written over an input: a mesh (also one below a
    directory argument), the baseline or the configuration file. Compared by real path and, for
    outputs that exist, by device and inode (a hard link is the same file).
    """
    outputs = [path for path in outputs if path is not None and path != STDOUT]
    if not outputs:
        return
    paths, inodes = set(), set()
    for path in _input_files([p for p in inputs if p is not None]):
        paths.add(os.path.realpath(path))
        try:
            info = os.stat(path)
        except OSError:
            continue
        inodes.add((info.st_dev, info.st_ino))
    for path in outputs:
        try:
            info = os.stat(path)
            same_inode = (info.st_dev, info.st_ino) in inodes
        except OSError:
            same_inode = False
        if same_inode or os.path.realpath(path) in paths:
            raise ConfigError(
                path,
                "is an input (a mesh, the baseline or the configuration): meshcheck does "
                "not write over its inputs",
            )


def _input_files(inputs):
    """The files the inputs stand for: files as given, and each mesh file below a directory."""
    for path in inputs:
        if not os.path.isdir(path):
            yield path
            continue
        from .load.formats import SUPPORTED_EXTENSIONS

        for folder, _, names in os.walk(path):
            for name in names:
                if os.path.splitext(name)[1].lower() in SUPPORTED_EXTENSIONS:
                    yield os.path.join(folder, name)


def _fail(exc: MeshcheckError):
    """Print ``error: PATH: reason`` on stderr, as one line, and exit with the error's status."""
    click.echo(f"error: {printable(str(exc))}", err=True)
    sys.exit(int(exc.exit_status))


def _interrupted():
    click.echo("error: interrupted", err=True)
    sys.exit(130)


def _is_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` was raised because of a Ctrl-C: a ``KeyboardInterrupt`` among its
    causes (pybind11 turns one met while an extension initialises, OpenCASCADE's, into
    ``ImportError("initialization failed")``)."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


@contextlib.contextmanager
def _interrupts_noted():
    """Note each Ctrl-C (SIGINT) the run gets in a list, and raise it as Python does. trimesh
    imports its optional modules under ``except BaseException``: a Ctrl-C met there is
    swallowed, and the half-made module fails later ("no graph engines available!"); that
    error is the interrupt's, not a bug. Outside the main thread, or where SIGINT has another
    handler than Python's, nothing is noted."""
    import signal
    import threading

    pressed: list[bool] = []
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield pressed
        return

    def note(signum, frame):
        pressed.append(True)
        signal.default_int_handler(signum, frame)

    signal.signal(signal.SIGINT, note)
    try:
        yield pressed
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextlib.contextmanager
def _interrupts_held():
    """Hold Ctrl-C (SIGINT) back while the block runs, and raise it when the block ends:
    trimesh imports its optional modules under ``except BaseException``, so a Ctrl-C raised
    during its import would be swallowed and the run go on, a module short. A handler of
    this process's notes the Ctrl-C instead of raising it (the signal is not masked: an
    extension that sets OpenCASCADE's own handlers as it loads would receive a masked one as
    it unmasks it, and crash). Outside the main thread nothing is held."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pressed: list[bool] = []
    before = signal.signal(signal.SIGINT, lambda *_: pressed.append(True))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)
    if pressed:
        raise KeyboardInterrupt


def _internal_error(exc: BaseException):
    """A bug: one line saying so and where the traceback is; exit ``ExitStatus.INTERNAL``."""
    import tempfile
    import traceback

    text = "".join(traceback.format_exception(exc))
    where = "the traceback is above"
    if os.environ.get(DEBUG_ENV):
        sys.stderr.write(text)
    else:
        try:
            fd, path = tempfile.mkstemp(prefix="meshcheck-crash-", suffix=".txt")
            with os.fdopen(fd, "w", encoding="utf-8", errors="backslashreplace") as fh:
                fh.write(text)
            where = f"the traceback is in {path}"
        except OSError:
            sys.stderr.write(text)
    what = printable(f"{type(exc).__name__}: {exc}")
    if len(what) > 200:
        what = what[:197] + "..."
    click.echo(
        f"error: internal error, a bug in meshcheck ({what}); {where}; please report it", err=True
    )
    sys.exit(int(ExitStatus.INTERNAL))


if __name__ == "__main__":  # pragma: no cover
    main()
