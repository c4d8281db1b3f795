"""STEP files -> solids: read and tessellated by OpenCASCADE (OCP), closed, in the file's own unit.

- ``document``: the bytes -> OpenCASCADE's XCAF document of placed solids, and the messages
  OpenCASCADE prints while it works, captured;
- ``assembly``: the structure checked (cycles, dangling and external references, solids outside
  every placed product), each solid instance walked to, named and placed;
- ``tessellate``: the solids meshed within a deflection of the CAD faces, closed;
- ``units``: the length unit the file declares, deflections in OpenCASCADE's millimetres;
- ``read``: ``read_step``, the file's tessellation from the cache (``cache.TessellationCache``) or
  from the above, and its exact solids (``StepSolids``) for the verify stage.

Each solid instance is a part named after its product (made unique in a fixed order: ``bolt``,
``bolt_1``...), placed by the composed transforms of the assembly, in double precision. The same
walk of the same bytes gives the exact solids (``StepSolids.by_node``), so the verify stage can
confirm a finding on the B-rep the part came from (``meshcheck.verify.brep``) without opening the
file again.

OpenCASCADE converts every length to millimetres, whatever the file declares; ``read_step``
converts back to the length unit the file declares, so that a millimetre STEP gives millimetres
and an inch STEP inches.
"""

from typing import TYPE_CHECKING

from ..._lazy import lazy_names

#: What a worker that reads or meshes STEP files imports before its first task
#: (``tessellate.preload``: OpenCASCADE): named here, where the command line finds it before it
#: imports numpy (``meshcheck.__main__``).
PREPARE = "meshcheck.load.step.tessellate:preload"

if TYPE_CHECKING:
    from .assembly import check_structure
    from .read import StepAssembly, StepSolids, read_step
    from .tessellate import (
        DEFAULT_ANGULAR_DEFLECTION,
        DEFAULT_DEFLECTION_MM,
        DEFAULT_RELATIVE_DEFLECTION,
        MAX_STEP_TRIANGLES,
        MIN_DEFLECTION_MM,
        MIN_RELATIVE_DEFLECTION,
        close_mesh,
        shape_diagonal,
    )
    from .units import step_unit

__all__ = [
    "DEFAULT_ANGULAR_DEFLECTION",
    "DEFAULT_DEFLECTION_MM",
    "DEFAULT_RELATIVE_DEFLECTION",
    "MAX_STEP_TRIANGLES",
    "MIN_DEFLECTION_MM",
    "MIN_RELATIVE_DEFLECTION",
    "StepAssembly",
    "StepSolids",
    "check_structure",
    "close_mesh",
    "read_step",
    "shape_diagonal",
    "step_unit",
]

# Imported on first use: a worker reading a file ahead (``ahead``) imports no trimesh.
__getattr__, __dir__ = lazy_names(
    __name__,
    {
        "check_structure": ".assembly",
        **dict.fromkeys(("StepAssembly", "StepSolids", "read_step"), ".read"),
        **dict.fromkeys(
            (
                "DEFAULT_ANGULAR_DEFLECTION",
                "DEFAULT_DEFLECTION_MM",
                "DEFAULT_RELATIVE_DEFLECTION",
                "MAX_STEP_TRIANGLES",
                "MIN_DEFLECTION_MM",
                "MIN_RELATIVE_DEFLECTION",
                "close_mesh",
                "shape_diagonal",
            ),
            ".tessellate",
        ),
        "step_unit": ".units",
    },
)
