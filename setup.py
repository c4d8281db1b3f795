"""Build the compiled geometry kernels (meshcheck.geometry._kernels) at ``pip install``.

Everything else about the package is in pyproject.toml; this file only declares the C++
extension, because it needs numpy's headers at build time.
"""

import sys
from pathlib import Path

import numpy
from setuptools import Extension, setup

SRC = Path("meshcheck/geometry/src")

# -ffp-contract=off: no fused multiply-adds, so every platform rounds the kernels' arithmetic
# the same way (the tolerances in constants.py assume plain IEEE double operations).
if sys.platform == "win32":
    COMPILE, LINK = ["/std:c++17", "/O2", "/fp:precise"], []
else:
    COMPILE, LINK = ["-O2", "-std=c++17", "-ffp-contract=off", "-pthread"], ["-pthread"]

setup(
    ext_modules=[
        Extension(
            "meshcheck.geometry._kernels",
            sources=[str(SRC / "kernels.cpp")],
            depends=sorted(str(p) for p in SRC.glob("*.hpp")),
            include_dirs=[numpy.get_include()],
            extra_compile_args=COMPILE,
            extra_link_args=LINK,
            language="c++",
        )
    ]
)
