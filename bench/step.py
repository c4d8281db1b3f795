"""STEP assemblies, whole processes: meshcheck cold and warm against trimesh + cascadio +
CollisionManager, and against the exact check a CAD user would script with OpenCASCADE.

Run from the repository root (needs the ``dev`` extra; ``pip install cascadio`` for the
CollisionManager peer)::

    python bench/step.py [FOLDER ...] [--jobs N] [--repeat N] [--parts NAME ...]

The assemblies: ``tests/data/step/*.STEP`` (real exports kept in the repository), two written here
by OpenCASCADE (a plate with three bolts line to line in their holes and a nut under each; 2,000
instances of one bolt at one placement), and every ``.step``/``.stp`` file in the folders given
(real exports fetched by hand, e.g. ``as1-oc-214.stp``, the AP214 assembly of
``tpaviot/pythonocc-demos``' ``assets/models``: plate, brackets, rod, bolts and nuts in nested
sub-assemblies).

``--parts NAME`` (repeatable) adds the file ``NAME`` of the folders written one solid per STEP
file, each where the assembly places it (``part_files``): parts exported one by one, checked
together as ``meshcheck part000.step part001.step ...``, the peers reading the same files.

For each, in this run, each a fresh process (imports included), alternated, best of ``--repeat``:

- ``cold``: ``meshcheck FILE -j N --format json`` with an empty cache directory and a fresh key;
- ``warm``: the same command again on the cache the cold run filled;
- ``CM``: ``cascadio.step_to_glb`` (OpenCASCADE's mesher at cascadio's defaults), ``trimesh.load``,
  ``CollisionManager.in_collision_internal`` (FCL): a clock only, its answers are wrong on every
  coincident fit;
- ``OCP``: ``STEPControl_Reader``, then every pair of solids whose boxes come within 1e-5 of the
  smaller diagonal: ``BRepAlgoAPI_Common`` (its volume) and ``BRepExtrema_DistShapeShape``;
  past 500 pairs the rest is estimated at the rate of the first 500 (the 2,000 coincident
  instances make 1,999,000 pairs).

Prints wall seconds and the ratios cold/CM, warm/CM, cold/OCP, then the same ratios of CPU
seconds (each process and the workers it waited for: less moved by other jobs on a shared
machine), with the load averages before and after. ``--peer cm FILE ...`` and
``--peer ocp FILE ...`` run one peer (what the table times).

``--phases`` prints instead where a cold run's CPU seconds go, for each assembly: one process
at ``-j 1`` without a cache, its imports (meshcheck with click and numpy; trimesh with scipy;
OpenCASCADE's bindings; the last two with the collector paused, as the command and its workers
import them: ``meshcheck._process``), OpenCASCADE reading the file (``read_document``), the
tessellation, the pairs decided on the B-rep (``decide_on_brep``; how many distinct pairs
``decide_pair`` decided, their mean, and the CPU seconds of their booleans alone: OpenCASCADE's
intersection and common solid, which an exact volume cannot do without), and the rest (broad
phase, filters, report), best of ``--repeat``.

meshcheck's modules are compiled to bytecode first, as an installed wheel has them (an editable
checkout run with ``PYTHONDONTWRITEBYTECODE`` would compile them again in every process).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")


def peer_cm(paths: list[str]) -> str:
    """trimesh + cascadio + CollisionManager on STEP files: the pairs it calls colliding."""
    import cascadio
    import trimesh

    manager = trimesh.collision.CollisionManager()
    solids = 0
    for k, path in enumerate(paths):
        with tempfile.TemporaryDirectory() as tmp:
            glb = os.path.join(tmp, "model.glb")
            cascadio.step_to_glb(path, glb)
            scene = trimesh.load(glb, force="scene")
        for node in scene.graph.nodes_geometry:
            transform, geometry = scene.graph[node]
            if isinstance(scene.geometry[geometry], trimesh.Trimesh):  # not its curves
                manager.add_object(f"{k}/{node}", scene.geometry[geometry], transform=transform)
                solids += 1
    _, names = manager.in_collision_internal(return_names=True)
    return f"{solids} solids, {len(names)} colliding pairs"


def peer_ocp(paths: list[str], max_pairs: int = 500) -> str:
    """The scripted exact check on the solids of STEP files: every box-overlapping pair of
    solids, boolean and distance (past ``max_pairs`` pairs, the rest is estimated at the rate
    of the first ones)."""
    import math

    from OCP.Bnd import Bnd_Box
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
    from OCP.BRepBndLib import BRepBndLib
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    solids = []
    for path in paths:
        reader = STEPControl_Reader()
        reader.ReadFile(path)
        reader.TransferRoots()
        explorer = TopExp_Explorer(reader.OneShape(), TopAbs_SOLID)
        while explorer.More():
            solids.append(explorer.Current())
            explorer.Next()
    boxes = []
    for solid in solids:
        box = Bnd_Box()
        BRepBndLib.Add_s(solid, box, False)
        boxes.append(box)
    counts = {"interference": 0, "touching": 0, "clear": 0}
    pairs = []
    for i in range(len(solids)):
        for j in range(i + 1, len(solids)):
            size = min(math.sqrt(boxes[k].SquareExtent()) for k in (i, j))
            if boxes[i].Distance(boxes[j]) <= 1e-5 * size:
                pairs.append((i, j, 1e-5 * size))
    start = time.perf_counter()
    for i, j, tolerance in pairs[:max_pairs]:
        props = GProp_GProps()
        BRepGProp.VolumeProperties_s(BRepAlgoAPI_Common(solids[i], solids[j]).Shape(), props)
        distance = BRepExtrema_DistShapeShape(solids[i], solids[j]).Value()
        if props.Mass() > math.pi / 6 * tolerance**3:
            counts["interference"] += 1
        else:
            counts["touching" if distance <= tolerance else "clear"] += 1
    text = f"{len(solids)} solids, {len(pairs)} pairs: {counts}"
    if len(pairs) > max_pairs:  # the rest at the rate of the first ones
        rest = (time.perf_counter() - start) * (len(pairs) - max_pairs) / max_pairs
        text += f" in the first {max_pairs}; the rest estimated at {rest:.1f} s\nestimated {rest!r}"
    return text


def phases(path: str) -> str:
    """CPU seconds of one cold run of ``meshcheck PATH -j 1`` in this process, by phase."""
    clock = time.process_time
    start = clock()
    import meshcheck._process  # first, as the command's entry point imports it
    import meshcheck.cli

    imports_uncollected = meshcheck._process.imports_uncollected

    marks = {"imports: meshcheck, click, numpy": clock() - start}
    mark = clock()
    with imports_uncollected():  # as the command imports the pipeline
        import trimesh  # noqa: F401

    marks["imports: trimesh, scipy"] = clock() - mark
    mark = clock()
    with imports_uncollected():  # as a worker imports it
        import OCP.OCP  # noqa: F401

    marks["imports: OpenCASCADE (OCP)"] = clock() - mark
    mark = clock()
    import meshcheck.pipeline
    import meshcheck.verify.brep
    import meshcheck.verify.solids

    marks["imports: meshcheck, click, numpy"] += clock() - mark
    spent = dict.fromkeys(("read_document", "tessellation", "decide_on_brep", "decide_pair"), 0.0)
    calls = dict.fromkeys(spent, 0)

    def timed_call(name, function):
        def call(*args, **kwargs):
            begin = clock()
            try:
                return function(*args, **kwargs)
            finally:
                spent[name] += clock() - begin
                calls[name] += 1

        return call

    from meshcheck.load.step import read

    read.read_document = timed_call("read_document", read.read_document)
    read._tessellation = timed_call("tessellation", read._tessellation)
    pipeline = meshcheck.pipeline
    pipeline.decide_on_brep = timed_call("decide_on_brep", pipeline.decide_on_brep)
    solids = meshcheck.verify.solids
    solids.decide_pair = timed_call("decide_pair", solids.decide_pair)
    booleans = [0.0]  # the pairs' intersections: pave filler and common solid

    class TimedIntersection(solids._Intersection):
        def __init__(self, *args):
            begin = clock()
            try:
                super().__init__(*args)
            finally:
                booleans[0] += clock() - begin

    solids._Intersection = TimedIntersection
    begin = clock()
    with quiet():
        try:
            meshcheck.cli.main(
                [path, "-j", "1", "--format", "json", "--no-cache", "-o", os.devnull],
                standalone_mode=False,
            )
        except SystemExit:
            pass
    run = clock() - begin
    marks["STEP read (OpenCASCADE transfer)"] = spent["read_document"]
    marks["tessellation"] = spent["tessellation"]
    marks["pairs on the B-rep (OpenCASCADE)"] = spent["decide_on_brep"]
    pairs, pair_seconds = calls["decide_pair"], spent.pop("decide_pair")
    marks["the rest (broad phase, filters, report)"] = run - sum(spent.values())
    detail = [pairs, pair_seconds, booleans[0]]
    return json.dumps({"total": clock() - start, "pairs": detail, **marks})


def print_phases(paths: list[str], repeat: int) -> None:
    """Each assembly's cold CPU seconds by phase (``phases``), best of ``repeat`` processes."""
    for path in paths:
        best: dict | None = None
        for _ in range(repeat):
            command = [sys.executable, __file__, "--peer", "phases", path]
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"phases failed on {path}:\n{done.stderr[-2000:]}")
            marks = json.loads(done.stdout.strip().splitlines()[-1])
            if best is None or marks["total"] < best["total"]:
                best = marks
        print(f"{os.path.basename(path)}: {best.pop('total'):.2f} s CPU")
        pairs, pair_seconds, boolean_seconds = best.pop("pairs")
        for name, seconds in best.items():
            print(f"  {name:42} {seconds:5.2f} s")
            if name.startswith("pairs on the B-rep") and pairs:
                each = pair_seconds / pairs
                print(f"    {pairs} distinct pairs: {pair_seconds:.2f} s, {each:.3f} s each")
                print(f"    their booleans (intersection, common solid): {boolean_seconds:.2f} s")


def compile_meshcheck() -> None:
    """meshcheck's modules compiled to bytecode, as an installed wheel has them."""
    import compileall

    compileall.compile_dir(os.path.join(ROOT, "meshcheck"), quiet=1)


def written_assemblies(folder: str) -> list[str]:
    """The assemblies written here by OpenCASCADE (tests/step_writer.py)."""
    import numpy as np

    sys.path.insert(0, os.path.join(ROOT, "tests"))
    sys.path.insert(0, os.path.join(ROOT, "sample_meshes"))
    from make_step_sample import bolt
    from step_writer import box, cut, cylinder, fuse, placement, write_step

    holes = (-20.0, 0.0, 20.0)
    plate = cut(box((-30, -10, 0), (30, 10, 6)), *[cylinder(2.5, -1, 7, x, 0) for x in holes])
    screw = fuse(cylinder(4.0, 6.0, 9.0), cylinder(2.5, -6.0, 6.0))
    nut = cut(box((-4, -4, -4), (4, 4, 0)), cylinder(2.5, -5, 1))
    instances = [("plate", np.eye(4))]
    for x in holes:
        instances += [("bolt", placement((x, 0, 0), 30.0)), ("nut", placement((x, 0, 0), 30.0))]
    out = []
    with quiet():
        out.append(
            write_step(
                os.path.join(folder, "fastened_plate.step"),
                {"plate": plate, "bolt": screw, "nut": nut},
                instances,
            )
        )
        out.append(
            write_step(
                os.path.join(folder, "bolt_2000_instances.step"),
                {"bolt": bolt(3.0)},
                [("bolt", np.eye(4))] * 2000,
            )
        )
    return [str(p) for p in out]


def part_files(path: str, folder: str) -> list[str]:
    """``path``'s solids written one per STEP file, each where the assembly places it (a part
    exported on its own, in the assembly's frame): the files a user checks together."""
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Reader, STEPControl_Writer
    from OCP.TopAbs import TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    reader = STEPControl_Reader()
    reader.ReadFile(path)
    reader.TransferRoots()
    out = os.path.join(folder, os.path.basename(path) + ".parts")
    os.makedirs(out)
    explorer, paths = TopExp_Explorer(reader.OneShape(), TopAbs_SOLID), []
    with quiet():
        while explorer.More():
            writer = STEPControl_Writer()
            writer.Transfer(explorer.Current(), STEPControl_AsIs)
            paths.append(os.path.join(out, f"part{len(paths):03d}.step"))
            writer.Write(paths[-1])
            explorer.Next()
    return paths


class quiet:
    """OpenCASCADE's writer messages on file descriptor 1 sent to /dev/null."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)

    def __exit__(self, *exc):
        sys.stdout.flush()
        os.dup2(self.saved, 1)
        os.close(self.saved)


def timed(command: list[str], env: dict) -> tuple[float, float, subprocess.CompletedProcess]:
    """(wall seconds, CPU seconds of the process and the workers it waited for, its outcome)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done


def bench_one(paths: list[str], jobs: int, repeat: int, has_cascadio: bool) -> dict:
    """Seconds of each column for one assembly (its files), best of ``repeat``, and what each
    found."""
    best: dict[str, float] = {}
    cpu: dict[str, float] = {}
    found: dict[str, str] = {}
    for attempt in range(repeat):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, MESHCHECK_CACHE_SECRET=f"bench-{os.getpid()}-{attempt}")
            command = [sys.executable, "-m", "meshcheck", *paths, "-j", str(jobs)]
            command += ["--format", "json", "--cache-dir", cache]
            runs = {"cold": command, "warm": command}
            if has_cascadio:
                runs["CM"] = [sys.executable, __file__, "--peer", "cm", *paths]
            runs["OCP"] = [sys.executable, __file__, "--peer", "ocp", *paths]
            reports = []
            for name, cmd in runs.items():
                seconds, cpu_seconds, done = timed(cmd, env)
                if done.returncode not in ((0, 1) if name in ("cold", "warm") else (0,)):
                    raise SystemExit(f"{name} failed on {paths[0]}:\n{done.stderr[-2000:]}")
                if name not in ("cold", "warm"):  # the peer's pairs past the ones it made
                    _, _, estimated = done.stdout.strip().partition("\nestimated ")
                    seconds += float(estimated or 0.0)  # at its rate
                    cpu_seconds += float(estimated or 0.0)
                best[name] = min(best.get(name, seconds), seconds)
                cpu[name] = min(cpu.get(name, cpu_seconds), cpu_seconds)
                if name in ("cold", "warm"):
                    reports.append(done.stdout)
                    summary = json.loads(done.stdout)["summary"]
                    found[name] = (
                        f"{summary['parts']} parts, {summary['pairs_checked']} pairs: "
                        + ", ".join(
                            f"{summary[k]} {k}"
                            for k in ("interference", "touching", "clearance", "duplicate")
                            if summary[k]
                        )
                    )
                else:
                    found[name] = done.stdout.strip().partition("\nestimated ")[0]
            if reports[0] != reports[1]:
                raise SystemExit(f"{paths[0]}: the warm report differs from the cold one")
    return {"seconds": best, "cpu": cpu, "found": found}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="*", help="folders of real STEP exports")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--peer", choices=("cm", "ocp", "phases"))
    parser.add_argument("--phases", action="store_true", help="cold CPU seconds by phase")
    parser.add_argument(
        "--parts",
        action="append",
        default=[],
        metavar="NAME",
        help="also time the file NAME of the folders written one solid per file",
    )
    args = parser.parse_args()
    if args.peer:
        peer = {"cm": peer_cm, "ocp": peer_ocp, "phases": lambda paths: phases(paths[0])}
        print(peer[args.peer](args.folders))
        return
    compile_meshcheck()
    try:
        import cascadio  # noqa: F401

        has_cascadio = True
    except ImportError:
        has_cascadio = False
        print("cascadio is not installed: no CollisionManager column (pip install cascadio)")
    print(f"load average {os.getloadavg()[0]:.1f} at the start")
    with tempfile.TemporaryDirectory() as folder:
        paths = sorted(glob.glob(os.path.join(ROOT, "tests", "data", "step", "*.STEP")))
        for extra in args.folders:
            paths += sorted(
                p
                for p in glob.glob(os.path.join(extra, "*"))
                if p.lower().endswith((".step", ".stp"))
            )
        paths += written_assemblies(folder)
        if args.phases:
            print_phases(paths, args.repeat)
            return
        cases = [(os.path.basename(p), [p]) for p in paths]
        for name in args.parts:
            found = [p for p in paths if os.path.basename(p) == name]
            if not found:
                raise SystemExit(f"--parts {name}: no such file in the folders")
            files = part_files(found[0], folder)
            cases.append((f"{len(files)} part files of {name}", files))
        head = f"{'assembly':30} {'cold':>7} {'warm':>7} {'CM':>7} {'OCP':>7}"
        print(
            head
            + f" {'cold/CM':>8} {'warm/CM':>8} {'cold/OCP':>9}  CPU: {'cold/CM':>7} {'cold/OCP':>8}"
        )
        rows = []
        for label, files in cases:
            result = bench_one(files, args.jobs, args.repeat, has_cascadio)
            s, c = result["seconds"], result["cpu"]
            cm, cm_cpu = s.get("CM", float("nan")), c.get("CM", float("nan"))
            print(
                f"{label[:30]:30} {s['cold']:>6.2f}s {s['warm']:>6.2f}s "
                f"{cm:>6.2f}s {s['OCP']:>6.2f}s {s['cold'] / cm:>7.2f}x {s['warm'] / cm:>7.2f}x "
                f"{s['cold'] / s['OCP']:>8.2f}x  CPU: {c['cold'] / cm_cpu:>6.2f}x "
                f"{c['cold'] / c['OCP']:>7.2f}x",
                flush=True,
            )
            rows.append((label, result["found"]))
    print("found:")
    for label, found in rows:
        print(f"  {label}")
        for name, text in found.items():
            print(f"    {name:5} {text}")
    print(f"load average {os.getloadavg()[0]:.1f} at the end; {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
