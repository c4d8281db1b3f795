"""meshcheck: do the parts of an assembly collide, touch, or come too close?

Example
-------
>>> import importlib.metadata, meshcheck
>>> result = meshcheck.check(["sample_meshes/plate.stl", "sample_meshes/bolt_m8_oversized.stl"])
>>> [(str(f.status), f.a) for f in result.findings]
[('interference', 'sample_meshes/bolt_m8_oversized.stl')]
>>> result.passed
False
>>> meshcheck.signed_distance([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 2], [1, 0, 2], [0, 1, 2]])
2.0
>>> meshcheck.__version__ == importlib.metadata.version("meshcheck-assembly")
True

The names below are imported on first use, so ``meshcheck --help`` does not pay for
trimesh and scipy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._lazy import lazy_names
from .errors import ConfigError, ExitStatus, InputError, MeshcheckError, MeshcheckWarning

# The name pip installs meshcheck by ("meshcheck" on PyPI is an unrelated project); the command
# and the import are meshcheck. Installed versions are read under this name.
DISTRIBUTION = "meshcheck-assembly"

if TYPE_CHECKING:
    from .geometry import Contact, Status, intersects, query, signed_distance
    from .outcome import CheckResult
    from .pipeline import check
    from .results import Finding, Location, PairVerdict, Part, Verdict
    from .settings import Settings

_LAZY = {
    "Contact": ".geometry",
    "Status": ".geometry",
    "intersects": ".geometry",
    "query": ".geometry",
    "signed_distance": ".geometry",
    "check": ".pipeline",
    "CheckResult": ".outcome",
    "Finding": ".results",
    "Location": ".results",
    "PairVerdict": ".results",
    "Part": ".results",
    "Verdict": ".results",
    "Settings": ".settings",
}

__all__ = [
    "CheckResult",
    "ConfigError",
    "Contact",
    "ExitStatus",
    "Finding",
    "InputError",
    "Location",
    "MeshcheckError",
    "MeshcheckWarning",
    "PairVerdict",
    "Part",
    "Settings",
    "Status",
    "Verdict",
    "check",
    "intersects",
    "query",
    "signed_distance",
]


_lazy_getattr, _lazy_dir = lazy_names(__name__, _LAZY)


def __getattr__(name: str):
    if name == "__version__":  # the one version: pyproject.toml's, as installed
        return _installed_version()
    return _lazy_getattr(name)


def _installed_version() -> str:
    """The installed distribution's version (``pyproject.toml``'s ``version``); ``0+unknown`` for
    a source tree that was never installed."""
    from importlib import metadata

    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "0+unknown"


def __dir__():
    return sorted(set(_lazy_dir()) | set(__all__) | {"__version__"})
