"""Build the compiled geometry kernels (meshcheck.geometry._kernels) at ``pip install``.

Everything else about the package is in pyproject.toml; this file only declares the C++
extension, because it needs numpy's headers at build time.

The extension uses only CPython's limited API (3.11 and later; numpy's headers support it), so
one wheel per platform, tagged ``cp311-abi3``, serves every Python from 3.11 on. The kernels
spend their time in plain C++ loops with the GIL released; ``python bench/abi3.py`` measured
the abi3 build as fast as the per-version one (docs/internals/benchmarks.md).
``MESHCHECK_LIMITED_API=0`` builds the per-version extension instead (for that comparison, and
for free-threaded Pythons, which have no stable ABI).
"""

import os
import sys
import sysconfig
from pathlib import Path

import numpy
from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

SRC = Path("meshcheck/geometry/src")

# The oldest Python the wheel runs on (pyproject's requires-python), as the limited API's
# version number and as the wheel tag.
LIMITED_API, ABI3_TAG = "0x030B0000", "cp311"
# Free-threaded builds of CPython have no stable ABI.
USE_LIMITED_API = os.environ.get(
    "MESHCHECK_LIMITED_API", "1"
) != "0" and not sysconfig.get_config_var("Py_GIL_DISABLED")

# -ffp-contract=off: no fused multiply-adds, so every platform rounds the kernels' arithmetic
# the same way (the tolerances in constants.py assume plain IEEE double operations).
if sys.platform == "win32":
    COMPILE, LINK = ["/std:c++17", "/O2", "/fp:precise"], []
else:
    COMPILE, LINK = ["-O2", "-std=c++17", "-ffp-contract=off", "-pthread"], ["-pthread"]


class BuildExt(build_ext):
    """build_ext that also deletes the kernels' other builds beside an in-place (editable) one.

    Python imports ``_kernels.cpython-311-*.so`` before ``_kernels.abi3.so``, so a per-version
    module left by an earlier build would shadow the fresh one and run stale kernels.
    """

    def run(self):
        super().run()
        if not (self.inplace or getattr(self, "editable_mode", False)):
            return
        for ext in self.extensions:
            built = Path(self.get_ext_filename(ext.name))
            for other in built.parent.glob(built.name.split(".")[0] + ".*"):
                if other.name != built.name and other.suffix in (".so", ".pyd"):
                    other.unlink()


setup(
    cmdclass={"build_ext": BuildExt},
    ext_modules=[
        Extension(
            "meshcheck.geometry._kernels",
            sources=[str(SRC / "kernels.cpp")],
            depends=sorted(str(p) for p in SRC.glob("*.hpp")),
            include_dirs=[numpy.get_include()],
            define_macros=[("Py_LIMITED_API", LIMITED_API)] if USE_LIMITED_API else [],
            py_limited_api=USE_LIMITED_API,
            extra_compile_args=COMPILE,
            extra_link_args=LINK,
            language="c++",
        )
    ],
    options={"bdist_wheel": {"py_limited_api": ABI3_TAG}} if USE_LIMITED_API else {},
)
