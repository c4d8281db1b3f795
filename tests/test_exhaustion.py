"""Running out of memory or file descriptors: one line naming what ran out, exit 6, never a bug
report, an abort, or an exit status that reads as a finding.

Each case runs in a subprocess that imports what a run imports, then caps itself (an
address-space limit a little above what it has mapped, or a descriptor limit at the lowest free
descriptor), so the cap falls inside the check wherever the machine's baseline is.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap

import pytest
import trimesh
from meshes import box

from meshcheck.errors import ExitStatus

pytestmark = pytest.mark.linux_only  # reads /proc/self/status, sets POSIX resource limits

#: Run the command with a limit set after its imports: ``KIND`` is ``memory`` (``AMOUNT`` MiB of
#: address space beyond what is mapped) or ``files`` (``AMOUNT`` descriptors beyond the lowest
#: free one).
CAPPED_RUN = textwrap.dedent(
    """
    import os, resource, sys
    import numpy, scipy.spatial, trimesh, manifold3d
    import meshcheck.cli, meshcheck.pipeline

    def mapped():
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024

    kind, amount = sys.argv[1], int(sys.argv[2])
    if kind == "memory":
        limit = mapped() + amount * 2**20
        resource.setrlimit(resource.RLIMIT_AS, (limit, resource.RLIM_INFINITY))
    else:
        free = os.dup(0)  # the lowest free descriptor
        os.close(free)
        hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
        resource.setrlimit(resource.RLIMIT_NOFILE, (free + amount, hard))
    sys.argv = ["meshcheck", *sys.argv[3:]]
    meshcheck.cli.main()
    """
)


def capped(kind: str, amount: int, *args, seconds: float = 120):
    """(exit status, stdout, stderr lines) of ``meshcheck ARGS`` under the cap."""
    proc = subprocess.run(
        [sys.executable, "-c", CAPPED_RUN, kind, str(amount), "--no-config", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=seconds,
        check=False,
    )
    return proc.returncode, proc.stdout, proc.stderr.splitlines()


def test_a_kernel_that_cannot_allocate_raises_memory_error():
    """std::bad_alloc in a compiled kernel is a MemoryError, not an abort (exit 134)."""
    code = textwrap.dedent(
        """
        import resource, numpy as np
        from meshcheck.geometry import _kernels
        with open("/proc/self/status") as fh:
            mapped = next(int(l.split()[1]) * 1024 for l in fh if l.startswith("VmSize:"))
        resource.setrlimit(resource.RLIMIT_AS, (mapped + (300 << 20), resource.RLIM_INFINITY))
        boxes = np.zeros((30000, 3)), np.ones((30000, 3))  # 9e8 overlapping pairs: 14 GB
        try:
            _kernels.box_pairs(*boxes, *boxes, 0.0)
        except MemoryError:
            print("MemoryError")
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert (proc.returncode, proc.stdout.strip()) == (0, "MemoryError"), proc.stderr


def test_a_boolean_without_room_raises_memory_error_instead_of_crashing():
    """manifold3d segfaults when an allocation fails: the boolean is refused first."""
    code = textwrap.dedent(
        """
        import resource, trimesh
        from meshcheck.verify.pair import shared_solid
        sphere = trimesh.creation.icosphere(subdivisions=6)  # 81,920 triangles: 53 MiB by the guard
        cube = trimesh.creation.box(extents=(1, 1, 1))
        with open("/proc/self/status") as fh:
            mapped = next(int(l.split()[1]) * 1024 for l in fh if l.startswith("VmSize:"))
        resource.setrlimit(resource.RLIMIT_AS, (mapped + (40 << 20), resource.RLIM_INFINITY))
        try:
            shared_solid(sphere.vertices, sphere.faces, cube.vertices, cube.faces)
        except MemoryError:
            print("MemoryError")
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert (proc.returncode, proc.stdout.strip()) == (0, "MemoryError"), proc.stderr


def test_too_little_address_space_to_start_is_one_line_and_exit_6():
    status, stdout, lines = capped("memory", 150, "--no-cache", "sample_meshes/plate.stl")
    assert status == ExitStatus.RESOURCES, lines
    assert re.fullmatch(
        r"error: out of memory: the address-space limit leaves 1\d\d MiB after start-up, "
        r"a check needs 320 MiB",
        lines[-1],
    ), lines
    assert stdout == ""


@pytest.fixture(scope="module")
def large_pair(tmp_path_factory):
    """An 81,920-triangle sphere and a box that cuts it."""
    folder = tmp_path_factory.mktemp("large")
    trimesh.creation.icosphere(subdivisions=6).export(folder / "sphere.stl")
    box(extents=(1, 1, 1), at=(1, 0, 0)).export(folder / "box.stl")
    return [folder / "sphere.stl", folder / "box.stl"]


def _whole_or_absent(args, mib, reference):
    """Run under a cap of ``mib``: one out-of-memory line and exit 6, or the uncapped report."""
    status, stdout, lines = capped("memory", mib, *args)
    assert not any("Traceback" in line or "internal error" in line for line in lines)
    if status == ExitStatus.RESOURCES:
        assert lines[-1].startswith("error: out of memory"), lines
        assert stdout == ""
    else:
        assert status == ExitStatus.FAILED, lines
        assert json.loads(stdout) == json.loads(reference)


@pytest.mark.slow
def test_a_large_boolean_under_memory_caps_is_whole_or_absent(large_pair):
    args = ["--no-cache", "-j", "1", "--format", "json", *large_pair]
    status, reference, _ = capped("memory", 4096, *args)
    assert status == ExitStatus.FAILED
    for mib in (330, 400):
        _whole_or_absent(args, mib, reference)


@pytest.mark.slow
def test_two_workers_under_memory_caps_are_whole_or_absent(tmp_path):
    """Across caps, every run either ends with the out-of-memory line (exit 6) or writes the
    same report as an uncapped run: never a partial report, never exit 1 without one (OpenBLAS
    calls exit(1) when its per-thread buffer cannot be mapped)."""
    paths = []
    for k in range(6):
        box(at=(k * 0.9, 0, 0)).export(tmp_path / f"p{k}.stl")
        paths.append(tmp_path / f"p{k}.stl")
    args = ["--no-cache", "-j", "2", "--format", "json", *paths]
    status, reference, _ = capped("memory", 4096, *args)
    assert status == ExitStatus.FAILED
    for mib in (330, 400):
        _whole_or_absent(args, mib, reference)


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_no_descriptor_left_is_one_line_naming_the_file_and_exit_6(jobs):
    sample = ["sample_meshes/plate.stl", "sample_meshes/bolt_m8_oversized.stl"]
    status, stdout, lines = capped("files", 0, "--no-cache", "-j", jobs, *sample)
    assert status == ExitStatus.RESOURCES, lines
    assert len(lines) == 1, lines
    assert re.fullmatch(
        r"error: sample_meshes/(plate|bolt_m8_oversized)\.stl: too many open files "
        r"\(the process's limit, ulimit -n\)",
        lines[0],
    ), lines
    assert stdout == ""


def test_too_few_descriptors_for_the_workers_is_one_line_and_exit_6(tmp_path):
    """Workers need pipes: with two descriptors free the files are read, the pool is not."""
    paths = []
    for k in range(40):
        box(at=(k * 0.9, 0, 0)).export(tmp_path / f"p{k:02d}.stl")
        paths.append(tmp_path / f"p{k:02d}.stl")
    status, _, lines = capped("files", 2, "--no-cache", "-j", "2", *paths)
    assert status in (ExitStatus.RESOURCES, ExitStatus.FAILED), lines
    if status == ExitStatus.RESOURCES:
        assert lines[-1] == "error: too many open files (the process's limit, ulimit -n)"
    assert not any("Traceback" in line or "internal error" in line for line in lines)
