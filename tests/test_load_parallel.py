"""Reading files in worker processes gives what reading them here gives, bit for bit: the same
arrays, names and order, the same warnings in the same order, the same first error."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from meshes import box
from test_load import write_3mf, write_gltf

from meshcheck.errors import InputError
from meshcheck.execute import LocalPool
from meshcheck.load import expand_paths, load_bodies
from meshcheck.load.files import StepOptions, parallel_pays, read_files
from meshcheck.load.limits import Budget, Limits

STEP = StepOptions(None, None, None)


@pytest.fixture(scope="module")
def pool():
    with LocalPool(2) as workers:
        yield workers


def assembly(folder) -> list[str]:
    """A small assembly in every worker format, with open, degenerate and instanced parts, and a
    3MF (read in the main process) in the middle."""
    folder.mkdir(exist_ok=True)
    paths = []
    for k in range(4):
        mesh = trimesh.creation.icosphere(subdivisions=1).apply_translation((3.0 * k, 0, 0))
        if k == 1:  # open: a "not closed" warning
            mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[2:], process=False)
        path = folder / f"a{k}.stl"
        mesh.export(path)
        paths.append(str(path))
    degenerate = box().apply_translation((0, 5, 0))
    faces = np.concatenate([degenerate.faces, [[0, 0, 1]]])  # a repeated vertex: dropped, warned
    path = folder / "b_degenerate.ply"
    trimesh.Trimesh(degenerate.vertices, faces, process=False).export(path)
    paths.append(str(path))
    paths.append(write_3mf(folder / "c_instances.3mf", [("left", (0, 9, 0)), ("right", (2, 9, 0))]))
    two = trimesh.util.concatenate([box(), box().apply_translation((0, 0, 3))])
    path = folder / "d_two_shells.obj"
    two.export(path)
    paths.append(str(path))
    paths.append(write_gltf(folder / "e_nodes.gltf", [("n1", (0, 0, 9)), ("n2", (4, 0, 9))]))
    overlapping = trimesh.util.concatenate([box(), box().apply_translation((0.5, 0, 20))])
    overlapping.vertices[len(overlapping.vertices) // 2 :, 2] -= 20  # shells sharing volume
    path = folder / "g_overlapping.stl"
    overlapping.export(path)
    paths.append(str(path))
    path = folder / "f_ascii.stl"
    path.write_text(trimesh.exchange.stl.export_stl_ascii(box().apply_translation((9, 9, 9))))
    paths.append(str(path))
    return paths


def read_both(paths, executor):
    """(FileReads, warnings) read here, then with ``executor`` (thresholds at zero)."""
    out = []
    for each in (None, executor):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            reads = read_files(
                paths,
                Budget(Limits()),
                STEP,
                executor=each,
                parallel=True,
            )
        out.append((reads, [str(w.message) for w in caught]))
    return out


def assert_same(serial, parallel):
    assert len(serial) == len(parallel)
    for a, b in zip(serial, parallel, strict=True):
        assert (a.declared, a.deflection) == (b.declared, b.deflection)
        assert [(n, g) for n, g, _ in a.items] == [(n, g) for n, g, _ in b.items]
        for (_, _, pa), (_, _, pb) in zip(a.items, b.items, strict=True):
            assert pa.tobytes() == pb.tobytes()
        for (va, fa, ca), (vb, fb, cb) in zip(a.geometries, b.geometries, strict=True):
            assert va.dtype == vb.dtype == np.float64 and fa.dtype == fb.dtype == np.int64
            assert va.tobytes() == vb.tobytes() and fa.tobytes() == fb.tobytes() and ca == cb


def test_parallel_reading_gives_the_serial_arrays_and_warnings(tmp_path, pool):
    paths = assembly(tmp_path / "parts")
    (serial, serial_warned), (parallel, parallel_warned) = read_both(paths, pool)
    assert serial_warned == parallel_warned
    assert any("not closed" in w for w in serial_warned)
    assert any("dropped 1 degenerate" in w for w in serial_warned)
    assert_same(serial, parallel)


def test_parallel_loading_gives_the_serial_bodies(tmp_path, pool):
    """Through load_bodies and the run's executor: names, digests, placements, order."""
    folder = tmp_path / "parts"
    assembly(folder)
    for split in (False, True):
        runs = []
        for executor in (None, pool):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                bodies = load_bodies([str(folder)], split=split, executor=executor, parallel=True)
            runs.append((bodies, [str(w.message) for w in caught]))
        (serial, serial_warned), (parallel, parallel_warned) = runs
        assert serial_warned == parallel_warned
        assert [b.name for b in serial] == [b.name for b in parallel]
        assert [b.relative_name for b in serial] == [b.relative_name for b in parallel]
        assert [b.digest for b in serial] == [b.digest for b in parallel]
        for a, b in zip(serial, parallel, strict=True):
            assert a.transform.tobytes() == b.transform.tobytes() and a.is_closed == b.is_closed


def test_the_first_failing_file_in_argument_order_is_the_error(tmp_path, pool):
    """Whatever order the workers finish in: a broken file early and a bigger one later."""
    paths = assembly(tmp_path / "parts")
    early = tmp_path / "parts" / "a2.stl"
    early.write_bytes(early.read_bytes()[:-7])  # truncated binary STL
    late = tmp_path / "parts" / "d_two_shells.obj"
    late.write_text("v 0 0 0\n" * 50_000)  # the biggest task (it starts first): no triangles
    errors = []
    for executor in (None, pool):
        with pytest.raises(InputError) as raised, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            read_files(paths, Budget(Limits()), STEP, executor=executor, parallel=True)
        errors.append(str(raised.value))
    assert errors[0] == errors[1]
    assert errors[0].startswith(f"{early}: truncated binary STL")


def test_the_run_budget_is_kept_in_file_order(tmp_path, pool):
    """A budget that runs out at the fifth file: the same file and message either way, though
    each worker read its files against an empty budget."""
    paths = assembly(tmp_path / "parts")
    errors = []
    for executor in (None, pool):
        with pytest.raises(InputError) as raised, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            read_files(
                paths,
                Budget(Limits(max_triangles=350)),
                STEP,
                executor=executor,
                parallel=True,
            )
        errors.append(str(raised.value))
    assert errors[0] == errors[1]
    assert "in earlier files exceed the limit of 350 triangles" in errors[0]


class LosingPool(LocalPool):
    """A real pool whose first task is reported lost, as ``LocalPool.map`` reports a task whose
    worker died (None)."""

    def map(self, function, tasks, **kwargs):
        results = super().map(function, tasks, **kwargs)
        return [None, *results[1:]]


def test_files_of_a_lost_worker_are_read_here(tmp_path):
    paths = assembly(tmp_path / "parts")
    with LosingPool(2) as losing:
        (serial, serial_warned), (parallel, parallel_warned) = read_both(paths, losing)
    assert serial_warned == parallel_warned
    assert_same(serial, parallel)


def test_small_runs_and_clusters_read_here(tmp_path):
    """When reading in workers does not pay, or the executor is a Dask cluster (loading stays on
    the client), no task is sent."""
    paths = expand_paths([str(p) for p in assembly(tmp_path / "parts")])
    assert not parallel_pays(paths, 2)
    big = tmp_path / "big.obj"
    trimesh.creation.icosphere(subdivisions=4).export(big)  # ~170 kB of text to parse
    assert parallel_pays([str(big)] * 400, 2) and not parallel_pays([str(big)] * 400, 1)
    assert not parallel_pays([str(big)] * 2, 2)

    class Counting(LocalPool):
        sent = 0

        def map(self, function, tasks, **kwargs):
            Counting.sent += len(tasks)
            return super().map(function, tasks, **kwargs)

    with Counting(2) as counting, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_files(paths, Budget(Limits()), STEP, executor=counting)  # does not pay
        counting.is_distributed = True
        read_files(paths, Budget(Limits()), STEP, executor=counting, parallel=True)
    assert Counting.sent == 0
