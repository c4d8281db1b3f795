"""The ``meshcheck`` command: parse options, call ``check``, render, exit. No geometry here.

Heavy modules (trimesh, numba, CoACD) are imported inside ``main`` only, so ``--help`` and usage
errors stay quick.
"""

from __future__ import annotations

import gc
import sys
import warnings

import click

from .config import FAIL_ON_CHOICES, NUMBER_RANGES, checked_number, parse_fail_on
from .errors import ConfigError, ExitStatus, MeshcheckError, MeshcheckWarning
from .report import FORMATS, exit_status, render, summary_line


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


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("files", nargs=-1, required=True)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(FORMATS),
    default="text",
    show_default=True,
    help="Report format: a table and a summary line, JSON, JUnit XML, or GitHub annotations.",
)
@click.option(
    "--output",
    "-o",
    "output",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    help="Write the report to this file instead of stdout (the summary line goes to stderr).",
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
    f"{', '.join(FAIL_ON_CHOICES)}; or none alone (nothing fails). "
    "Default: interference, plus clearance when a clearance is set.",
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
    help="Where decompositions are kept. Default: the user's cache directory.",
)
@click.option("--no-cache", is_flag=True, help="Neither read nor write cached decompositions.")
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
    'needs pip install "meshcheck[dask]"). Default: $MESHCHECK_SCHEDULER, then the config '
    "file's scheduler; none runs locally.",
)
@click.option(
    "--export",
    "export_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write the assembly with clashes marked in red to this .glb file.",
)
@click.version_option(package_name="meshcheck")
def main(
    fmt,
    files,
    output,
    clearance,
    tolerance,
    threshold,
    fail_on,
    split,
    config_path,
    no_config,
    cache_dir,
    no_cache,
    jobs,
    scheduler,
    export_path,
):
    """Check the parts in FILES for interference, contact and clearance.

    FILES are mesh files (STL, OBJ, PLY, OFF, GLB/GLTF, 3MF) or directories (every mesh file
    below them). A part is named by its path as given; a body inside a file holding several is
    PATH#NODE.

    Exit status: 0 when nothing fails, 1 when a finding fails the run (interference by default,
    and clearance violations when --clearance is given), 2 for a usage or configuration error,
    3 when an input cannot be checked.
    """
    from .settings import Settings

    try:
        if no_config and config_path is None:
            config = None
        else:
            config = "auto" if config_path is None else config_path
        settings = Settings.from_options(
            config=config,
            clearance=clearance,
            tolerance=tolerance,
            threshold=threshold,
            fail_on=fail_on,
            split=split,
            cache_dir=cache_dir,
            use_cache=not no_cache,
            jobs=jobs,
            scheduler=scheduler,
        )
    except MeshcheckError as exc:
        _fail(exc)

    from .progress import Progress

    with Progress("starting", 0):  # numba, trimesh, scipy: seconds on a cold disk
        from .pipeline import check

    error = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshcheckWarning)
        try:
            result = check(files, settings)
            if export_path is not None:
                from .export import export_clashes

                export_clashes(export_path, result.bodies, result.findings)
        except MeshcheckError as exc:
            error = exc
    for w in caught:
        if issubclass(w.category, MeshcheckWarning):
            click.echo(f"warning: {w.message}", err=True)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
    if error is not None:
        _fail(error)

    text = render(result, fmt)
    if output is None:
        click.echo(text, nl=False)
    else:
        try:
            with open(output, "w", encoding="utf-8") as f:
                f.write(text)
        except OSError as exc:
            click.echo(f"error: {output}: cannot write the report ({exc.strerror})", err=True)
            sys.exit(int(ExitStatus.USAGE))
        click.echo(f"{summary_line(result)}; report written to {output}", err=True)
    # The report is out. Freezing the heap spares the interpreter's exit-time collections a walk
    # over the ~135k objects numpy, scipy, trimesh and numba created: 0.2 s of a 1.5 s warm run.
    gc.freeze()
    sys.exit(int(exit_status(result)))


def _fail(exc: MeshcheckError):
    """Print ``error: PATH: reason`` on stderr and exit with the error's status."""
    click.echo(f"error: {exc}", err=True)
    sys.exit(int(exc.exit_status))


if __name__ == "__main__":  # pragma: no cover
    main()
