"""Files -> bodies: every body in world coordinates and one report unit, with the name reports use.

Naming
------
Names are a function of the arguments and of each file's content and structure only (never of
hash seeds, random numbers or the order of a dict), so they and the finding IDs built from them
are the same on every run.

- A part's name is the path exactly as given (``plate.stl``).
- A body inside a file that holds several is named ``PATH#NODE``; bodies of one file are listed
  sorted by NODE. NODE is:

  - glTF/GLB: the node's ``name``, else its index in the file's node list; a name an earlier
    node already has gets ``_2``, ``_3``... A node whose mesh has several triangle primitives
    gives one body per primitive, ``NODE/0``, ``NODE/1``... by primitive index.
  - 3MF: the build item's object ``name``, else ``object<ID>``; an object made of components
    gives one body per mesh it reaches, ``ITEM/COMPONENT`` (the component object's ``name``,
    else ``component<k>`` counting from 1); a name used twice gets ``_2``, ``_3``... in build order.
  - OBJ: the ``o``/``g`` name; STL: the ``solid`` name; unnamed ones ``geometry_<k>`` in file
    order (trimesh's names, made unique in file order).
  - STEP: the product name of each solid (``load.step``), repeated instances ``PRODUCT_1``,
    ``PRODUCT_2``...; a STEP part is always ``PATH#PRODUCT``, even alone in its file.
  - URDF: the link, every collision element of a link in one part (``load.urdf``); a URDF
    part is always ``PATH#LINK``.

  A geometry instanced by two nodes gives two parts that share one local mesh (``Body.mesh``)
  and differ by ``Body.transform``.
- A directory argument stands for every supported mesh file below it, recursively, sorted by
  relative path, hidden files and folders skipped; each is named ``os.path.join(ARG, RELPATH)``.
- With ``split=True`` a body made of several disconnected shells becomes one part per shell,
  named ``NAME#1``, ``NAME#2``... in the order of each shell's first triangle in the file. A closed
  inward-facing shell (a cavity lining) inside another shell stays with that shell.
- ``Body.relative_name`` is the name relative to its argument: ``RELPATH[#NODE]`` below a
  directory argument, ``basename(PATH)[#NODE]`` for a file argument (for pattern matching).
- Two inputs giving the same part name are an error.

Units
-----
Every body is converted to one report unit (``Body.units``) by a scale folded into
``Body.transform``; ``Body.mesh`` stays in the file's unit. The rule is ``meshcheck.units``'s:
``units`` names the unit of files that declare none and the report unit; without it undeclared
files are millimetres and the report unit is the one all files declare, when all declare the same,
else millimetres. ``file_units`` (``units.UnitRule``: ``--units FILE=UNIT``) give files their
unit whatever they declare, and then count as what those files declare. Files whose sizes differ
by ``sizes.MIXED_UNITS_RATIO`` or more raise a warning (likely mixed units), and so does a file
whose size is implausible for mechanical parts (``sizes.LARGE_METRES`` across or more,
``sizes.SMALL_METRES`` or less), each suggesting the ``--units FILE=UNIT`` that would make it
plausible.

Validation
----------
Every input problem the user can fix is an ``InputError`` (``error: PATH: reason``, one line):
missing or unreadable paths, unknown extensions, empty or truncated files, files or declared
sizes beyond the run's ``Limits`` (checked before reading: file sizes, 3MF entry sizes and
component fan-out, glTF buffers and accessors, STL/PLY/OFF counts, triangles and parts per run),
glTF nodes that do not form a tree, files without triangles (point clouds), NaN or infinite
coordinates, and placements that flatten a part or take its coordinates beyond
``Limits.max_coordinate``. Triangles with a repeated vertex are dropped with a warning; triangles
of zero area with three distinct vertices are kept (they keep a closed surface closed). Meshes
that are not closed are kept. Each of those raises a ``MeshcheckWarning`` whose message starts
with the part name. (A file whose closed shells overlap each other is kept too; the check warns
about it, ``verify.shells``: the test is the verify stage's.)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:
    from ..mesh import is_closed, split_shells
    from .bodies import load_assembly, load_bodies, load_file, split_body
    from .body import (
        Assembly,
        Body,
        LocalGeometry,
        local_geometries,
        local_geometry,
        mesh_digest,
    )
    from .formats import SUPPORTED_EXTENSIONS
    from .limits import Limits
    from .paths import expand_paths

__all__ = [
    "SUPPORTED_EXTENSIONS",
    "Assembly",
    "Body",
    "Limits",
    "LocalGeometry",
    "expand_paths",
    "is_closed",
    "load_assembly",
    "load_bodies",
    "load_file",
    "local_geometries",
    "local_geometry",
    "mesh_digest",
    "split_body",
    "split_shells",
]

# Imported on first use: a STEP file's reader (``step.document``) imports no trimesh.
__getattr__, __dir__ = lazy_names(
    __name__,
    {
        **dict.fromkeys(("is_closed", "split_shells"), "..mesh"),
        **dict.fromkeys(("load_assembly", "load_bodies", "load_file", "split_body"), ".bodies"),
        **dict.fromkeys(
            (
                "Assembly",
                "Body",
                "LocalGeometry",
                "local_geometries",
                "local_geometry",
                "mesh_digest",
            ),
            ".body",
        ),
        "SUPPORTED_EXTENSIONS": ".formats",
        "Limits": ".limits",
        "expand_paths": ".paths",
    },
)
