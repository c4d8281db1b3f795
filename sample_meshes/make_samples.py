"""Write the sample assembly: a plate with four bolt holes, four M6 bolts, an L-bracket.

Run from the repository root: ``python sample_meshes/make_samples.py``. Units are millimetres.

- ``plate.stl``: 100 x 60 x 10 plate with four 6.6 mm clearance holes.
- ``bolt_m6_a.stl`` .. ``bolt_m6_c.stl``: M6 bolts (6 mm shank) in three holes, heads resting on
  the plate: touching, radial clearance about 0.29 mm.
- ``bolt_m8_oversized.stl``: an 8 mm shank pushed into the fourth 6.6 mm hole: interference.
- ``bracket.stl``: an L-bracket standing on the plate: touching.
"""

from __future__ import annotations

import os

import numpy as np
import trimesh

HERE = os.path.dirname(os.path.abspath(__file__))
SECTIONS = 32  # facets around every hole and shank; keeps the files small
HOLES = [(-35.0, -15.0), (-35.0, 15.0), (35.0, -15.0), (35.0, 15.0)]


def cylinder(radius: float, z0: float, z1: float, x: float = 0.0, y: float = 0.0):
    c = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=SECTIONS)
    c.apply_translation([x, y, 0.5 * (z0 + z1)])
    return c


def box(lower, upper):
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    b = trimesh.creation.box(extents=upper - lower)
    b.apply_translation(0.5 * (lower + upper))
    return b


def plate():
    body = box([-50, -30, 0], [50, 30, 10])
    holes = [cylinder(3.3, -1, 11, x, y) for x, y in HOLES]
    return trimesh.boolean.difference([body, *holes], engine="manifold")


def bolt(x: float, y: float, shank_radius: float):
    head = cylinder(5.0, 10.0, 14.0, x, y)
    shank = cylinder(shank_radius, -4.0, 10.0, x, y)
    return trimesh.boolean.union([head, shank], engine="manifold")


def bracket():
    base = box([-10, -10, 10], [20, 10, 14])
    upright = box([16, -10, 14], [20, 10, 40])
    return trimesh.boolean.union([base, upright], engine="manifold")


def main() -> None:
    parts = {
        "plate.stl": plate(),
        "bolt_m6_a.stl": bolt(*HOLES[0], 3.0),
        "bolt_m6_b.stl": bolt(*HOLES[1], 3.0),
        "bolt_m6_c.stl": bolt(*HOLES[2], 3.0),
        "bolt_m8_oversized.stl": bolt(*HOLES[3], 4.0),
        "bracket.stl": bracket(),
    }
    for name, mesh in parts.items():
        assert mesh.is_watertight, name
        mesh.export(os.path.join(HERE, name))
        print(f"{name}: {len(mesh.faces)} triangles")


if __name__ == "__main__":
    main()
