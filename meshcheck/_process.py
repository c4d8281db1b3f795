"""Process-wide settings of the ``meshcheck`` command, made before numpy is imported.

The command line imports this module first. Library users (``meshcheck.check``) keep their own
environment.

- One OpenBLAS thread per process (unless the user chose otherwise): meshcheck's parallel work
  runs in its own worker processes and compiled kernels, and OpenBLAS maps a buffer per thread
  at its first call; when that mapping fails under an address-space limit it prints "Memory
  allocation still failed" and calls ``exit(1)``, which would read as "a finding failed the
  run". One thread needs one buffer (and is as fast here: the sample and a 300-part assembly run
  in the same time).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
