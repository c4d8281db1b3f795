"""Write the sample assembly as one STEP file: ``sample_meshes/assembly.step``.

Run from the repository root: ``python sample_meshes/make_step_sample.py`` (needs the ``dev``
extra: OpenCASCADE through cadquery-ocp). Units are millimetres. The same parts as
``make_samples.py``, as a CAD system exports them: exact cylinders, one ``bolt_m6`` product
placed three times.

- ``plate``: 100 x 60 x 10 plate with four 6.6 mm clearance holes.
- ``bolt_m6`` (three instances: ``bolt_m6``, ``bolt_m6_1``, ``bolt_m6_2``): M6 bolts (6 mm shank)
  in three holes, heads resting on the plate: touching, radial clearance 0.3 mm.
- ``bolt_m8_oversized``: an 8 mm shank pushed into the fourth 6.6 mm hole: interference,
  0.7 mm deep.
- ``bracket``: an L-bracket standing on the plate: touching.
"""

from __future__ import annotations

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

from step_writer import box, cut, cylinder, fuse, placement, write_step  # noqa: E402

HOLES = [(-35.0, -15.0), (-35.0, 15.0), (35.0, -15.0), (35.0, 15.0)]


def bolt(shank_radius: float):
    """A bolt in its own frame: head 10 mm wide from z = 10 to 14, shank from z = -4 to 10."""
    return fuse(cylinder(5.0, 10.0, 14.0), cylinder(shank_radius, -4.0, 10.0))


def main() -> None:
    plate = cut(box((-50, -30, 0), (50, 30, 10)), *[cylinder(3.3, -1, 11, x, y) for x, y in HOLES])
    bracket = fuse(box((-10, -10, 10), (20, 10, 14)), box((16, -10, 14), (20, 10, 40)))
    path = os.path.join(HERE, "assembly.step")
    write_step(
        path,
        {"plate": plate, "bolt_m6": bolt(3.0), "bolt_m8_oversized": bolt(4.0), "bracket": bracket},
        [
            ("plate", placement()),
            *[("bolt_m6", placement((x, y, 0.0))) for x, y in HOLES[:3]],
            ("bolt_m8_oversized", placement((*HOLES[3], 0.0))),
            ("bracket", placement()),
        ],
        assembly="sample_assembly",
    )
    print(f"{os.path.relpath(path)}: {os.path.getsize(path)} bytes", file=sys.stderr)


if __name__ == "__main__":
    main()
