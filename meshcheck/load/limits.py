"""Budgets on what a run reads, checked before reading wherever a file declares a size."""

from __future__ import annotations

import os
import stat
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, resource_error


@dataclass(frozen=True)
class Limits:
    """Bounds on the input of one run; anything beyond them is refused with an ``InputError``.

    Each bound is checked before the data it bounds is read or allocated where the file declares
    a size (STL and PLY headers, zip entries, glTF buffers and accessors, 3MF component trees),
    and once more on what was actually read. The defaults admit real assemblies of a few
    million triangles with room to spare; raise them for giant ones.

    Attributes
    ----------
    max_triangles : int
        Triangles in the whole run, every placed instance counted (a screw placed 200 times
        counts 200 times: each is checked on its own). Default 50 million.
    max_file_bytes : int
        Bytes of one input file, of one 3MF archive member once decompressed, and of one glTF
        buffer. Default 4 GiB.
    max_parts : int
        Parts in the whole run, after instancing (3MF build items times the meshes their
        components reach, glTF mesh nodes times their primitives). Default 1 million.
    max_coordinate : float
        Largest absolute coordinate allowed, in the file's unit before placement and in the
        report unit after it. Far beyond any real part (1e12 mm is a million kilometres), and far
        enough below the float64 range that products of coordinates in the exact kernels never
        overflow. Default 1e12.
    """

    max_triangles: int = 50_000_000
    max_file_bytes: int = 4 << 30
    max_parts: int = 1_000_000
    max_coordinate: float = 1e12


class Budget:
    """What a run has used of its ``Limits`` so far."""

    def __init__(self, limits: Limits):
        self.limits = limits
        self.triangles = 0
        self.parts = 0

    def check_triangles(self, path: str, count: int, what: str = "triangles") -> None:
        """Refuse ``count`` more triangles when they would exceed the run's limit."""
        limit = self.limits.max_triangles
        if count > limit - self.triangles:
            before = f" after {self.triangles} in earlier files" if self.triangles else ""
            raise InputError(
                path,
                f"{num(count)} {what}{before} exceed the limit of {num(limit)} triangles per run "
                "(raise it with --max-triangles)",
            )

    def check_parts(self, path: str, count: int, what: str = "parts") -> None:
        """Refuse ``count`` more parts when they would exceed the run's limit."""
        limit = self.limits.max_parts
        if count > limit - self.parts:
            raise InputError(
                path,
                f"{num(count)} {what} exceed the limit of {num(limit)} per run",
            )

    def take(self, path: str, triangles: int, parts: int) -> None:
        """Count what a file added, refusing it when it exceeds a limit."""
        self.check_triangles(path, triangles)
        self.check_parts(path, parts)
        self.triangles += triangles
        self.parts += parts


#: Candidate part pairs (bounding boxes that meet) a run verifies at most. A dense real assembly
#: of 10,000 parts has a few tens of thousands; 2,000 copies of one part at one spot have 2
#: million (hours of verification, gigabytes of memory). More is refused with exit 3.
MAX_CANDIDATE_PAIRS = 500_000


def check_candidate_pairs(count: int, parts: int) -> None:
    """Refuse a run whose broad phase leaves more than ``MAX_CANDIDATE_PAIRS`` part pairs.

    Raises
    ------
    InputError
        Saying how many pairs among how many parts, and the likely cause.
    """
    if count > MAX_CANDIDATE_PAIRS:
        raise InputError(
            None,
            f"{num(count)} candidate part pairs (bounding boxes that meet) among {num(parts)} "
            f"parts exceed the limit of {num(MAX_CANDIDATE_PAIRS)} per run: many copies of a part "
            "at one place? (check fewer parts at once, or split the assembly with [groups])",
        )


def num(count: int) -> str:
    """A count as messages print it: ``1_000_000`` from 100,000 on, so big ones read at a glance.

    >>> num(12), num(2_500_000)
    ('12', '2_500_000')
    """
    return f"{count:,}".replace(",", "_") if count >= 100_000 else str(count)


#: Longest line a text mesh format (OBJ, OFF) may have: a polygon of 10,000 corners fits many
#: times over. A longer one is refused as it is read, before it is held or parsed.
MAX_TEXT_LINE = 1 << 20
#: Bytes of a file's start handed to a reader's ``check`` before the rest is read.
HEAD_BYTES = 4096


def read_file(
    path: str,
    limits: Limits,
    *,
    check: Callable[[bytes, int], None] | None = None,
    max_line: int | None = None,
) -> bytes:
    """The bytes of a regular file, refusing what cannot be read or is over ``max_file_bytes``.

    The file is opened once and checked through its descriptor, so what is checked is what is
    read; a FIFO or device is refused without blocking on it.

    Parameters
    ----------
    check : callable, optional
        ``check(head, size)`` with the first ``HEAD_BYTES`` and the file's size, before the rest
        is read: a reader's budget checks on what its header declares.
    max_line : int, optional
        Refuse the file, as soon as it is met, at a line longer than this many bytes.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise resource_error(exc, path) or InputError(
            path, f"cannot be read ({exc.strerror or exc})"
        ) from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(path, "is a directory")
        if not stat.S_ISREG(info.st_mode):
            raise InputError(path, "is not a regular file")
        size = info.st_size
        if size == 0:
            raise InputError(path, "empty file")
        if size > limits.max_file_bytes:
            raise InputError(
                path,
                f"file has {num(size)} bytes, over the limit of {num(limits.max_file_bytes)}",
            )
        chunks = []
        left, run = size, 0
        if check is not None:  # the head, read first (os.pread is not on Windows)
            head = os.read(fd, min(HEAD_BYTES, size))
            check(head, size)
            if max_line is not None:
                run = _longest_line(path, head, run, max_line)
            chunks.append(head)
            left -= len(head)
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 24))
            if not chunk:
                break
            if max_line is not None:
                run = _longest_line(path, chunk, run, max_line)
            chunks.append(chunk)
            left -= len(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise resource_error(exc, path) or InputError(
            path, f"cannot be read ({exc.strerror or exc})"
        ) from None
    finally:
        os.close(fd)


def _longest_line(path: str, chunk: bytes, run: int, limit: int) -> int:
    """Refuse a line longer than ``limit`` in ``chunk``, given the ``run`` of bytes since the
    last newline before it; the run at its end."""
    newlines = np.flatnonzero(np.frombuffer(chunk, dtype=np.uint8) == 10)
    if not len(newlines):
        longest, run = run + len(chunk), run + len(chunk)
    else:
        gaps = np.diff(newlines) - 1
        longest = max(run + int(newlines[0]), int(gaps.max(initial=0)))
        run = len(chunk) - 1 - int(newlines[-1])
    if max(longest, run) > limit:
        raise InputError(
            path,
            f"has a line over {num(limit)} bytes long: not a mesh file meshcheck reads",
        )
    return run


def check_placement(
    name: str,
    vertices: np.ndarray,
    transform: np.ndarray,
    limits: Limits,
    *,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    """Refuse a placement that is not finite, flattens the part, or overflows its coordinates.

    Parameters
    ----------
    vertices : (n, 3) float64
        The mesh in its own frame.
    transform : (4, 4) float64
        Frame -> world, report units.
    bounds : ((3,), (3,)) float64, optional
        The per-axis minimum and maximum of ``vertices``, when the caller has them.
    """
    transform = np.asarray(transform, dtype=np.float64)
    if not np.all(np.isfinite(transform)):
        raise InputError(name, "placement transform holds NaN or infinite values")
    is_identity = np.array_equal(transform, IDENTITY)  # a part stored where it sits
    with np.errstate(all="ignore"):
        lo, hi = bounds if bounds is not None else (vertices.min(axis=0), vertices.max(axis=0))
        if is_identity:  # the box's own corners, unmoved
            largest = max(_largest(lo), _largest(hi))
        else:
            largest = _largest(box_corners(lo, hi) @ transform[:3, :3].T + transform[:3, 3])
        if not largest <= limits.max_coordinate:  # the box's corners bound; the vertices decide
            largest = _largest(vertices @ transform[:3, :3].T + transform[:3, 3])
        if not largest <= limits.max_coordinate:
            shown = "beyond the float range" if not np.isfinite(largest) else f"{largest:.3g}"
            raise InputError(
                name,
                f"placed coordinates reach {shown}, beyond the {limits.max_coordinate:g} "
                "meshcheck can check exactly",
            )
        if not is_identity and is_singular(transform[:3, :3]):
            raise InputError(
                name, "placement transform is singular (it flattens the part or collapses it)"
            )


def doubtful_placements(
    transforms: np.ndarray, lower: np.ndarray, upper: np.ndarray, limits: Limits
) -> np.ndarray:
    """Which of many placements ``check_placement`` might refuse, in one pass: those not finite,
    whose box corners reach beyond ``limits.max_coordinate``, or that are singular. The rest
    pass it for sure; the caller asks ``check_placement`` about these, in order, for its verdict
    and its message.

    Parameters
    ----------
    transforms : (n, 4, 4) float64
        Frame -> world, report units.
    lower, upper : (n, 3) float64
        Each placed mesh's box in its own frame.

    Returns
    -------
    (n,) bool
    """
    transforms = np.asarray(transforms, dtype=np.float64).reshape(-1, 4, 4)
    with np.errstate(all="ignore"):
        finite = np.all(np.isfinite(transforms), axis=(1, 2))
        linear, shift = transforms[:, :3, :3], transforms[:, :3, 3]
        boxes = box_corners(np.asarray(lower)[:, None, :], np.asarray(upper)[:, None, :])
        corners = np.einsum("nij,nkj->nki", linear, boxes) + shift[:, None]
        largest = np.abs(corners).max(axis=(1, 2), initial=0.0)
        doubtful = ~finite | ~(largest <= limits.max_coordinate)
        moved = np.flatnonzero(~doubtful & ~np.all(transforms == IDENTITY, axis=(1, 2)))
        if len(moved):
            singular = np.linalg.svd(linear[moved], compute_uv=False)
            doubtful[moved] = ~(singular[:, -1] > SINGULAR_RATIO * singular[:, 0])
    return doubtful


#: A placement whose smallest singular value is below this fraction of its largest flattens the
#: part: float64 keeps ~16 digits, and a real scale never spans 12 orders of magnitude.
SINGULAR_RATIO = 1e-12


def is_singular(linear: np.ndarray) -> bool:
    """True when the (3, 3) linear part of a placement collapses a volume (all zeros included).

    Examples
    --------
    >>> is_singular(np.zeros((3, 3))), is_singular(np.diag([1.0, 0.0, 1.0])), is_singular(np.eye(3))
    (True, True, False)
    """
    singular = np.linalg.svd(np.asarray(linear, dtype=np.float64), compute_uv=False)
    return not singular[-1] > SINGULAR_RATIO * singular[0]


IDENTITY = np.eye(4)
#: Which corner of a box takes the upper bound on each axis: corner k, axis d <=> bit d of k.
_UPPER = (np.arange(8)[:, None] >> np.arange(3) & 1).astype(bool)


def box_corners(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of the box ``lower..upper``; corner k takes ``upper`` on axis d
    when bit d of k is set."""
    return np.where(_UPPER, upper, lower)


def _largest(points: np.ndarray) -> float:
    value = float(np.max(np.abs(points)))
    return value if np.isfinite(value) else np.inf
