"""Process-wide settings of the ``meshcheck`` command and its workers, made before numpy is
imported.

The command line imports this module first, and a worker process before its imports
(``_worker.main``). Library users (``meshcheck.check``) keep their own environment; the workers
a library call starts are meshcheck's processes, with these settings.

- One OpenBLAS thread per process (unless the user chose otherwise): meshcheck's parallel work
  runs in its own worker processes and compiled kernels, and OpenBLAS maps a buffer per thread
  at its first call; when that mapping fails under an address-space limit it prints "Memory
  allocation still failed" and calls ``exit(1)``, which would read as "a finding failed the
  run". One thread needs one buffer (and is as fast here: the sample and a 300-part assembly run
  in the same time).
- The cyclic garbage collector passes over its youngest generation every
  ``COLLECTOR_THRESHOLD`` allocations, not Python's 700, and so over the older ones (counted in
  passes of the youngest) that much less often too. Importing OpenCASCADE's bindings (one
  extension of tens of thousands of types and functions), numpy, scipy and trimesh allocates
  hundreds of thousands of objects that live as long as the process; at Python's default the
  collector walks them again and again while they are made (``perf record python -c "import
  OCP.TopoDS"`` shows ``gc_collect_main`` first). Cyclic garbage is still collected, later.
  Workers set the same (``_worker.main``). The largest imports (the pipeline's here, a worker's
  prepared ones) run with the collector paused, and what they made is frozen after them
  (``imports_uncollected``): the collector never walks it again.
"""

from __future__ import annotations

import contextlib
import gc
import os

#: Allocations between two collections of the youngest generation (Python's default: 700).
COLLECTOR_THRESHOLD = 10_000


def tune_collector() -> None:
    """Collect the youngest generation every ``COLLECTOR_THRESHOLD`` allocations (or less
    often, when the process already asked for that); the older generations as before."""
    young, *older = gc.get_threshold()
    if young:  # 0: the collector is off, and stays off
        gc.set_threshold(max(young, COLLECTOR_THRESHOLD), *older)


@contextlib.contextmanager
def imports_uncollected():
    """No collection while the block runs (imports: what they make lasts as long as the
    process); then every object tracked so far is frozen (``gc.freeze``: left out of every later
    collection, and of a forked child's copies), and the collector is as it was. The garbage
    made before the block is collected first (milliseconds: the heap is small before the large
    imports), so none of it is frozen, in a process that runs the command more than once too."""
    was_enabled = gc.isenabled()
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was_enabled:
            gc.enable()


os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
tune_collector()
