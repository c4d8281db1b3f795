"""STEP fits decided on the tessellation alone and on the B-rep: what each settles, and its cost.

Run from the repository root (needs the ``dev`` extra, for OpenCASCADE's STEP writer)::

    python bench/brep.py

Prints, all measured in this run:

1. For each fit (a pin line to line with its hole at several radii and deflections, press fits of
   0.01-0.05 mm on the diameter, a 0.001 mm gap), the CAD truth (OpenCASCADE's boolean common
   volume of the solids as written), the verdict of the meshes alone (the verify stage, the pair
   tolerance floored at the two deflections), and the verdict on the B-rep
   (``verify.brep``): each wrong verdict is marked.
2. The cost: the check of each fit on the B-rep against the check on the meshes alone (the
   bodies without their solids), in the same process, and the whole check of the sample
   assembly both ways (best of 3).
3. Importing OpenCASCADE's bindings (OCP, which reads STEP) against cascadio (the reader before),
   each in a fresh interpreter, alternated, best of 3.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import subprocess
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))

import numpy as np  # noqa: E402
from step_writer import annulus_volume, box, cut, cylinder, placement  # noqa: E402
from step_writer import write_step as _write_step  # noqa: E402

from meshcheck import pipeline  # noqa: E402
from meshcheck.load import load_bodies  # noqa: E402
from meshcheck.results import Verdict  # noqa: E402

EYE = np.eye(4)
# (hole radius, pin radius, deflection mm or None for the default)
FITS = [
    (1.5, 1.5, None),
    (3.0, 3.0, None),
    (3.0, 3.0, 0.02),
    (6.0, 6.0, 0.002),
    (12.5, 12.5, None),
    (12.5, 12.5, 0.05),
    (3.0, 3.005, None),
    (3.0, 3.01, None),
    (3.0, 3.025, None),
    (3.0, 3.004, 0.02),
    (3.0, 2.999, None),
]


@contextlib.contextmanager
def quiet():
    """OpenCASCADE's writer messages on file descriptor 1 sent to /dev/null."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "wb") as null:
        os.dup2(null.fileno(), 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def write_fit(path: str, hole: float, pin: float) -> tuple[str, float]:
    """A pin through a 4 mm housing; the file and the solids' common volume (closed form)."""
    half = 1.4 * hole + 1.0
    housing = cut(box((-half, -half, 0), (half, half, 4)), cylinder(hole, -1, 5))
    pin_solid = cylinder(pin, -1, 5)
    with quiet():
        _write_step(
            path,
            {"housing": housing, "pin": pin_solid},
            [("housing", EYE), ("pin", placement(angle_deg=7.0))],
        )
    return path, annulus_volume(hole, pin, 4.0)


def truth(hole: float, pin: float, common: float) -> str:
    if common > 0:
        return f"interference {pin - hole:.3g}"
    return "touching" if pin == hole else f"gap {hole - pin:.3g}"


def verdict(findings) -> str:
    if not findings:
        return "clear"
    (f,) = findings
    if f.status == Verdict.INTERFERENCE:
        return f"interference {f.depth:.3g}"
    return str(f.status)


def timed_check(bodies, *, confirm: bool):
    """(findings, seconds) of one check: on the B-rep, or on the meshes alone (the bodies without
    their solids)."""
    if not confirm:
        bodies = [dataclasses.replace(b, brep=None) for b in bodies]
    start = time.perf_counter()
    findings = pipeline.check_bodies(bodies, jobs=1).findings
    return findings, time.perf_counter() - start


def fits_table(tmp: str) -> None:
    print("1. Fits: CAD truth, meshes alone, B-rep (x: wrong)")
    print(f"   {'hole':>5} {'pin':>6} {'defl':>6}  {'truth':<18} {'meshes':<18} {'B-rep':<18}")
    wrong = {"meshes": 0, "brep": 0}
    verify_s, brep_s = [], []
    for k, (hole, pin, deflection) in enumerate(FITS):
        path, common = write_fit(os.path.join(tmp, f"fit{k}.step"), hole, pin)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            bodies = load_bodies([path], step_deflection=deflection)
            mesh_only, t_verify = timed_check(bodies, confirm=False)
            confirmed, t_brep = timed_check(bodies, confirm=True)
        expected = truth(hole, pin, common)
        row = []
        for name, findings in (("meshes", mesh_only), ("brep", confirmed)):
            text = verdict(findings)
            ok = text.split()[0] == expected.split()[0] or (
                expected.startswith("gap") and text == "clear"
            )
            wrong[name] += not ok
            row.append(f"{text}{'' if ok else ' x'}")
        verify_s.append(t_verify)
        brep_s.append(t_brep)
        defl = "0.005" if deflection is None else f"{deflection:g}"
        print(f"   {hole:>5} {pin:>6} {defl:>6}  {expected:<18} {row[0]:<18} {row[1]:<18}")
    print(
        f"   wrong: meshes alone {wrong['meshes']} of {len(FITS)}, with the B-rep {wrong['brep']}"
    )
    ratio = np.median(np.array(brep_s) / np.array(verify_s))
    print(
        f"2. check of one fit on the B-rep: median {np.median(brep_s) * 1e3:.0f} ms, "
        f"{ratio:.2f}x the check on the meshes alone (median of {len(brep_s)})"
    )


def sample_run() -> None:
    path = os.path.join(ROOT, "sample_meshes", "assembly.step")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bodies = load_bodies([path])
        times = {True: [], False: []}
        for _ in range(3):
            for confirm in (False, True):
                t = time.perf_counter()
                timed_check(bodies, confirm=confirm)
                times[confirm].append(time.perf_counter() - t)
    with_, without = min(times[True]), min(times[False])
    print(
        f"   sample assembly check (loaded bodies, best of 3): {with_:.2f} s on the B-rep, "
        f"{without:.2f} s on the meshes alone: {with_ / without:.2f}x"
    )


def imports() -> None:
    code = {
        "OCP": "from OCP.STEPCAFControl import STEPCAFControl_Reader",
        "cascadio": "import cascadio",
    }
    best = {}
    for _ in range(3):
        for name, statement in code.items():
            t = time.perf_counter()
            done = subprocess.run([sys.executable, "-c", statement], capture_output=True)
            elapsed = time.perf_counter() - t
            if done.returncode == 0:
                best[name] = min(best.get(name, elapsed), elapsed)
    if "cascadio" not in best:
        print(f"3. import OCP (STEP reader) {best['OCP']:.2f} s; cascadio not installed")
        return
    print(
        f"3. import OCP (STEP reader) {best['OCP']:.2f} s, cascadio {best['cascadio']:.2f} s: "
        f"{best['OCP'] / best['cascadio']:.2f}x (fresh interpreters, best of 3)"
    )


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        fits_table(tmp)
    sample_run()
    imports()


if __name__ == "__main__":
    main()
