"""Arguments -> files: each directory stands for the supported mesh files below it."""

from __future__ import annotations

import os
from collections.abc import Iterable

from ..errors import InputError
from .formats import SUPPORTED_EXTENSIONS


def expand_paths(paths: Iterable[str]) -> list[str]:
    """Replace each directory in ``paths`` by the supported mesh files below it.

    Parameters
    ----------
    paths : iterable of str
        Files and directories, as the user gave them.

    Returns
    -------
    files : list of str
        Files in argument order; a directory's files sorted by relative path and joined to it.

    Raises
    ------
    InputError
        A path does not exist, or a directory holds no supported mesh file.
    """
    return [path for path, _ in named_files(paths)]


def named_files(paths: Iterable[str]) -> list[tuple[str, str]]:
    """(file, name relative to its argument) of every file the arguments stand for."""
    files: list[tuple[str, str]] = []
    for path in paths:
        if os.path.isdir(path):
            found = sorted(walk_meshes(path))
            if not found:
                exts = ", ".join(SUPPORTED_EXTENSIONS)
                raise InputError(path, f"directory holds no mesh files ({exts})")
            files.extend((os.path.join(path, rel), rel) for rel in found)
        elif os.path.exists(path):
            files.append((path, os.path.basename(path) or path))
        else:
            raise InputError(path, "no such file or directory")
    return files


def walk_meshes(root: str) -> list[str]:
    """Relative paths of supported mesh files below ``root``, skipping hidden entries."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if not d.startswith(".")]
        rel_dir = os.path.relpath(dirpath, root)
        for name in filenames:
            ext = os.path.splitext(name)[1].lower()
            if name.startswith(".") or ext not in SUPPORTED_EXTENSIONS:
                continue
            out.append(name if rel_dir == os.curdir else os.path.join(rel_dir, name))
    return out
