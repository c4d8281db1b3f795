"""``python -m meshcheck``: the same command as the ``meshcheck`` script."""

from .cli import main

main(prog_name="meshcheck")
