"""STEP input: what tessellation costs and how far its answers are from the CAD model.

Run from the repository root (needs the ``dev`` extra, for OpenCASCADE's STEP writer)::

    python bench/step_tessellation.py

Prints, all measured in this run:

1. Tessellation time per part of the sample assembly (each product written to its own STEP file,
   read with ``read_step``), triangles and file size, at the default deflection against
   0.01 mm and a coarse 0.1 mm: the ratios are the price of the default.
2. Pin-in-hole accuracy: a pin with 0.1 mm radial clearance and one 0.2 mm too big, for a small
   (3.1 mm) and a large (25 mm) hole, measured by ``check_bodies`` from the tessellation, against
   the CAD truth, for several deflections. The promise: clearance within 0.01 mm, depth within
   0.03 mm, at the default.
3. The sample assembly end to end: its STEP file against the STL files of ``make_samples.py``
   (sizes; load and check times, same process).

``python bench/step_tessellation.py --mend FOLDER ...`` prints instead, for every ``.step`` and
``.stp`` file in the folders (real exports fetched by hand, as for ``bench/step.py``):

4. The faces BRepMesh cannot mesh at the default deflection, which ``mend_faces`` meshes again
   with a coarser deflection inside: for each factor of ``MEND_INTERIOR_FACTORS`` (and 2), how
   many it meshes, and the CPU seconds its successful and failed tries cost.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
sys.path.insert(0, os.path.join(ROOT, "sample_meshes"))

from make_step_sample import HOLES, bolt  # noqa: E402
from step_writer import box, cut, cylinder, fuse, placement, write_step  # noqa: E402

from meshcheck.load import Body, load_bodies  # noqa: E402
from meshcheck.load.step import DEFAULT_DEFLECTION_MM, read_step  # noqa: E402
from meshcheck.pipeline import check_bodies  # noqa: E402

DEFLECTIONS = (0.1, 0.02, 0.01, DEFAULT_DEFLECTION_MM, 0.0025)


def best_of(fn, repeat=3):
    """Smallest wall time of ``repeat`` calls, seconds, and the last result."""
    times, result = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return min(times), result


def quiet(fn, *args, **kwargs):
    """Call ``fn`` with OpenCASCADE's messages on file descriptor 1 sent to /dev/null."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "wb") as null:
        os.dup2(null.fileno(), 1)
        try:
            return fn(*args, **kwargs)
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def per_part(tmp):
    plate = cut(box((-50, -30, 0), (50, 30, 10)), *[cylinder(3.3, -1, 11, x, y) for x, y in HOLES])
    bracket = fuse(box((-10, -10, 10), (20, 10, 14)), box((16, -10, 14), (20, 10, 40)))
    parts = {"plate": plate, "bolt_m6": bolt(3.0), "bolt_m8": bolt(4.0), "bracket": bracket}
    print("1. Tessellation time per part (best of 5; read_step: OpenCASCADE + welding)")
    head = f"{'part':10} {'STEP bytes':>10}"
    for d in (DEFAULT_DEFLECTION_MM, 0.01, 0.1):
        head += f" {f'{d:g} mm: ms':>14} {'triangles':>9}"
    print(head + f" {'ms ratio':>9}")
    ratios = []
    for name, shape in parts.items():
        path = quiet(
            write_step, os.path.join(tmp, f"{name}.step"), {name: shape}, [(name, placement())]
        )
        row = f"{name:10} {os.path.getsize(path):>10}"
        times = []
        for d in (DEFAULT_DEFLECTION_MM, 0.01, 0.1):
            seconds, asm = best_of(lambda d=d, path=path: read_step(path, deflection=d), repeat=5)
            times.append(seconds)
            row += f" {1e3 * seconds:>14.1f} {sum(len(m.faces) for _, m, _ in asm.items):>9}"
        ratios.append(times[0] / times[1])
        print(row + f" {times[0] / times[1]:>8.2f}x")
    print(f"   default / 0.01 mm: {statistics.median(ratios):.2f}x time (median)")


def pins(tmp):
    print("\n2. Pin in hole, measured from the tessellation vs CAD truth (mm)")
    print(
        f"{'hole r':>7} {'deflection':>10} {'clearance (0.1)':>16} {'error':>8}"
        f" {'depth (0.2)':>12} {'error':>8} {'triangles':>9}"
    )
    for hole in (3.1, 25.0):
        half = max(10.0, 1.4 * hole)
        housing = cut(box((-half, -half, 0), (half, half, 10)), cylinder(hole, -1, 11))
        files = {}
        for label, radius in (("clear", hole - 0.1), ("over", hole + 0.2)):
            files[label] = quiet(
                write_step,
                os.path.join(tmp, f"{label}{hole}.step"),
                {"housing": housing, "pin": cylinder(radius, -2, 12)},
                [("housing", placement()), ("pin", placement(angle_deg=7.0))],
            )
        for d in DEFLECTIONS:
            found = {}
            triangles = 0
            for label, path in files.items():
                asm = read_step(path, deflection=d)
                triangles = max(triangles, sum(len(m.faces) for _, m, _ in asm.items))
                bodies = [Body(f"{path}#{n}", path, m, t) for n, m, t in asm.items]
                (finding,) = check_bodies(bodies, clearance=0.5, jobs=1).findings
                found[label] = finding
            gap = found["clear"].distance
            depth = found["over"].depth
            mark = "  <- default" if d == DEFAULT_DEFLECTION_MM else ""
            print(
                f"{hole:>7g} {d:>10g} {gap:>16.5f} {gap - 0.1:>+8.5f}"
                f" {depth:>12.5f} {depth - 0.2:>+8.5f} {triangles:>9}{mark}"
            )


def sample():
    print("\n3. Sample assembly: STEP against the STL files (same parts)")
    step = os.path.join(ROOT, "sample_meshes", "assembly.step")
    stls = sorted(
        os.path.join(ROOT, "sample_meshes", f)
        for f in os.listdir(os.path.join(ROOT, "sample_meshes"))
        if f.endswith(".stl")
    )
    step_bytes = os.path.getsize(step)
    stl_bytes = sum(os.path.getsize(f) for f in stls)
    print(
        f"   files: STEP {step_bytes} bytes, STL {stl_bytes} bytes ({step_bytes / stl_bytes:.2f}x)"
    )
    t_step, step_bodies = best_of(lambda: load_bodies([step]))
    t_stl, stl_bodies = best_of(lambda: load_bodies(stls))
    tri_step = sum(len(b.mesh.faces) for b in step_bodies)
    tri_stl = sum(len(b.mesh.faces) for b in stl_bodies)
    print(
        f"   load: STEP {1e3 * t_step:.1f} ms ({tri_step} triangles), "
        f"STL {1e3 * t_stl:.1f} ms ({tri_stl} triangles): {t_step / t_stl:.1f}x"
    )
    c_step, r_step = best_of(lambda: check_bodies(step_bodies, jobs=1), repeat=1)
    c_stl, r_stl = best_of(lambda: check_bodies(stl_bodies, jobs=1), repeat=1)
    print(
        f"   check (no cache, 1 job): STEP {c_step:.2f} s, STL {c_stl:.2f} s: {c_step / c_stl:.2f}x"
    )
    for result in (r_step, r_stl):
        worst = max(result.findings, key=lambda f: f.depth or 0.0)
        print(f"   {worst.a}: depth {worst.depth:.4f} (CAD 0.7)")


def mend_survey(paths: list[str]) -> None:
    """4. The faces ``mend_faces`` meshes again at the default deflection, in each STEP file
    (those BRepMesh leaves without triangles or short of their edges, in a solid whose welded
    mesh is not closed): for each interior deflection factor, tried alone on a fresh copy of
    each product, how many it meshes, and the CPU seconds of the solids' tries that meshed
    every face and of those that did not."""
    import io

    from OCP.BRep import BRep_Builder
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.IMeshTools import IMeshTools_Parameters
    from OCP.TopoDS import TopoDS_Shape

    from meshcheck.load.step import tessellate as t
    from meshcheck.load.step.document import read_document
    from meshcheck.mesh import is_closed

    factors = (2, 4, 8, 16)
    print("4. faces meshed again (mend_faces): interior deflection factor, faces it meshes")
    for path in paths:
        with open(path, "rb") as f:
            instances = read_document(f.read(), path)
        products = {i.product_key: i.product for i in instances}
        diagonal = max(t.shape_diagonal(shape) for shape in products.values())
        deflection = t._honoured_deflection(None, diagonal, path, "mm", 1.0)
        angle = t.DEFAULT_ANGULAR_DEFLECTION
        tried = dict.fromkeys(factors, 0)
        meshed = dict.fromkeys(factors, 0)
        seconds = {f: [0.0, 0.0] for f in factors}  # meshed, failed
        needing = set()
        for key, product in products.items():
            text = t.brep_text(product)
            for factor in factors:
                shape = TopoDS_Shape()
                BRepTools.Read_s(shape, io.BytesIO(text), BRep_Builder())
                quiet(BRepMesh_IncrementalMesh, shape, deflection, False, angle, False)
                for n, (solid, is_solid) in enumerate(t._solids_and_rest(shape)):
                    if not is_solid or is_closed(t._welded(solid, path, 1.0, deflection)):
                        continue  # what product_mesh leaves as meshed
                    broken = [face for face in t._faces(solid) if not t.follows_edges(face)]
                    needing.update((key, n, k) for k in range(len(broken)))
                    for face in broken:
                        BRep_Builder().UpdateFace(face, None)
                    params = IMeshTools_Parameters()
                    params.Deflection, params.Angle = deflection, angle
                    params.DeflectionInterior = factor * deflection
                    start = time.process_time()
                    quiet(BRepMesh_IncrementalMesh, t._compound(broken), params)
                    ok = sum(t.follows_edges(face) for face in broken)
                    seconds[factor][0 if ok == len(broken) else 1] += time.process_time() - start
                    tried[factor] += len(broken)
                    meshed[factor] += ok
        products_needing = len({key for key, _, _ in needing})
        print(f"   {os.path.basename(path)}: {len(needing)} faces of {products_needing} products")
        for factor in factors:
            if tried[factor]:
                done, failed = seconds[factor]
                print(
                    f"     x{factor:<2} {meshed[factor]:3} of {tried[factor]:3} meshed, "
                    f"{done:6.2f} s; tries that left some {failed:6.2f} s"
                )


def main():
    warnings.simplefilter("ignore")
    if sys.argv[1:2] == ["--mend"]:
        paths = [
            os.path.join(folder, name)
            for folder in sys.argv[2:]
            for name in sorted(os.listdir(folder))
            if name.lower().endswith((".step", ".stp"))
        ]
        mend_survey(paths)
        return
    with tempfile.TemporaryDirectory() as tmp:
        per_part(tmp)
        pins(tmp)
    sample()


if __name__ == "__main__":
    main()
