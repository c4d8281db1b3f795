"""The ``meshcheck`` command: parse options, call ``check``, render, exit. No geometry here."""

from __future__ import annotations

import sys

import click

from .decompose import DEFAULT_THRESHOLD
from .errors import ExitStatus, MeshcheckError
from .report import FORMATS, exit_status, render


def default_cache_dir() -> str:
    """The user's cache directory for meshcheck (platform convention)."""
    import platformdirs

    return platformdirs.user_cache_dir("meshcheck")


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("files", nargs=-1, required=True)
@click.option(
    "--format", "fmt", type=click.Choice(FORMATS), default="text", show_default=True,
    help="Report format on stdout.",
)
@click.option(
    "--clearance", type=click.FloatRange(min=0.0), default=None,
    help="Also report part pairs closer than this distance (model units); they fail the run.",
)
@click.option(
    "--tolerance", type=click.FloatRange(min=0.0), default=None,
    help="Overlaps and gaps below this count as touching (model units). "
    "Default: 1e-5 of the assembly's bounding-box diagonal.",
)
@click.option(
    "--threshold", type=click.FloatRange(min=0.01, max=1.0), default=DEFAULT_THRESHOLD,
    show_default=True, help="CoACD concavity threshold for the convex pieces.",
)
@click.option(
    "--cache-dir", type=click.Path(file_okay=False), default=None,
    help="Where decompositions are kept. Default: the user's cache directory.",
)
@click.option("--no-cache", is_flag=True, help="Neither read nor write cached decompositions.")
@click.option(
    "--jobs", "-j", type=click.IntRange(min=1), default=None,
    help="Processes for decomposition. Default: all cores.",
)
@click.option(
    "--export", "export_path", type=click.Path(dir_okay=False), default=None,
    help="Write the assembly with clashes marked in red to this .glb file.",
)
@click.version_option(package_name="meshcheck")
def main(fmt, files, clearance, tolerance, threshold, cache_dir, no_cache, jobs, export_path):
    """Check the parts in FILES for interference, contact and clearance.

    Exit status: 0 when nothing fails, 1 when a part pair interferes (or violates --clearance),
    2 for a usage error, 3 when an input cannot be checked.
    """
    from .pipeline import check

    if no_cache:
        cache_dir = None
    elif cache_dir is None:
        cache_dir = default_cache_dir()
    try:
        result = check(
            files,
            clearance=clearance,
            tolerance=tolerance,
            threshold=threshold,
            cache_dir=cache_dir,
            jobs=jobs,
            export=export_path,
        )
    except MeshcheckError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(int(exc.exit_status))
    click.echo(render(result, fmt), nl=False)
    sys.exit(int(exit_status(result)))


if __name__ == "__main__":  # pragma: no cover
    main()
