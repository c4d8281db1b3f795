"""A package's names imported on first use (PEP 562): importing one light module of a package
(a worker reading a STEP file needs OpenCASCADE, not trimesh) does not import every module
beside it."""

from __future__ import annotations

import importlib
import sys


def lazy_names(package: str, names: dict[str, str]):
    """``__getattr__`` and ``__dir__`` for the module ``package``: each name of ``names`` is
    imported from its module (relative to ``package``) when first asked for, then kept.

    Examples
    --------
    >>> getattr_, dir_ = lazy_names("meshcheck", {"InputError": ".errors"})
    >>> getattr_("InputError").__name__
    'InputError'
    """

    def __getattr__(name: str):
        if name in names:
            value = getattr(importlib.import_module(names[name], package), name)
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return __getattr__, __dir__
