"""A content-addressed store of convex decompositions, one ``.npz`` file per mesh and setting.

Modelled on black's ``src/black/cache.py``: a plain directory (the user's cache directory by
default, any directory CI can persist), entries named by a key built from the mesh's content hash,
the decomposition settings, the CoACD version and this file's format version. Entries are written
to a temporary file in the same directory and moved into place with ``os.replace``, so a reader sees
a whole entry or none, and two runs sharing the directory at once both succeed (the last writer
wins with an identical entry). Arrays are read with ``allow_pickle=False``; an entry that is
truncated, garbled, of the wrong shapes, or whose checksum does not match counts as a miss and is
rewritten.

Trust: the cache is input from outside like any mesh (CI restores it from an artifact store), and
its checksum is plain SHA-256 of public data, so anyone can forge an entry. The checksum only
catches accidents. What keeps a forged entry from changing a verdict is that the pipeline uses a
decomposition only after checking that its pieces cover every triangle of the mesh
(``decompose.covers``); a forged or stale entry that does not is recomputed. Pieces that cover the
mesh but are too big only cost time: the verify stage decides every pair they let through.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import itertools
import json
import os
import tempfile
import zipfile

import numpy as np

# Bump when the layout of an entry or the meaning of a decomposition changes (e.g. the triangle
# cover fix-up): old entries are then simply never looked up again.
FORMAT_VERSION = 2


def cache_key(digest: str, options: dict) -> str:
    """Key of a decomposition: hex SHA-256 of the mesh digest, options and library versions.

    Parameters
    ----------
    digest : str
        Hex digest of the frame-local (translation-normalised) mesh.
    options : dict
        Every option that changes the pieces (CoACD settings); JSON-serialisable.

    Returns
    -------
    key : str
        64 hex characters.
    """
    payload = {
        "format": FORMAT_VERSION,
        "coacd": coacd_version(),
        "digest": digest,
        "options": options,
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@functools.cache
def coacd_version() -> str:
    """Installed CoACD version, read from package metadata (without importing CoACD)."""
    import importlib.metadata

    try:
        return importlib.metadata.version("coacd")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - a required dependency
        return "unknown"


class DecompositionCache:
    """Convex pieces stored under ``directory``, looked up by ``cache_key``.

    Parameters
    ----------
    directory : str
        Cache root; created on the first write.

    Examples
    --------
    >>> import tempfile
    >>> cache = DecompositionCache(tempfile.mkdtemp())
    >>> cache.put("ab" * 32, [np.eye(3)])
    >>> [p.tolist() for p in cache.get("ab" * 32)]
    [[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]]
    """

    def __init__(self, directory: str):
        self.root = os.path.join(os.fspath(directory), f"decompositions-v{FORMAT_VERSION}")

    def path(self, key: str) -> str:
        """File of the entry for ``key``."""
        return os.path.join(self.root, key[:2], f"{key}.npz")

    def get(self, key: str) -> list[np.ndarray] | None:
        """The pieces stored for ``key``, or None when missing or unusable.

        Returns
        -------
        pieces : list of (n_i, 3) float64, or None
            Exactly the arrays given to ``put`` (bit for bit).
        """
        try:
            if not _sizes_agree(self.path(key)):
                return None
            with np.load(self.path(key), allow_pickle=False) as data:
                if sorted(data.files) != ["checksum", "points", "starts"]:
                    return None
                points, starts, checksum = data["points"], data["starts"], data["checksum"]
        except (OSError, ValueError, EOFError, KeyError, MemoryError, zipfile.BadZipFile):
            return None
        if not _valid(points, starts, checksum, key):
            return None
        return [points[a:b].copy() for a, b in itertools.pairwise(starts)]

    def put(self, key: str, pieces: list[np.ndarray]) -> None:
        """Store ``pieces`` for ``key`` atomically; a failure to write only costs a recompute.

        Parameters
        ----------
        key : str
            From ``cache_key``.
        pieces : list of (n_i, 3) float64
            Convex piece vertices.
        """
        points = np.ascontiguousarray(
            np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in pieces])
            if pieces
            else np.empty((0, 3)),
            dtype=np.float64,
        )
        sizes = [len(np.asarray(p).reshape(-1, 3)) for p in pieces]
        starts = np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]).astype(np.int64)
        checksum = np.frombuffer(_checksum(points, starts, key), dtype=np.uint8)
        final = self.path(key)
        try:
            os.makedirs(os.path.dirname(final), exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=os.path.dirname(final), prefix=".tmp-", suffix=".npz")
        except OSError:
            return
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, points=points, starts=starts, checksum=checksum)
            os.replace(tmp, final)
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        _remove_stale_temporaries(os.path.dirname(final))


# A temporary file older than this was left by a writer that was killed before its os.replace.
STALE_SECONDS = 3600.0


def _remove_stale_temporaries(directory: str) -> None:
    import time

    cutoff = time.time() - STALE_SECONDS
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            if entry.name.startswith(".tmp-") and entry.stat().st_mtime < cutoff:
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _sizes_agree(path: str) -> bool:
    """True when every array in the ``.npz`` at ``path`` declares no more data than it holds.

    Read before ``np.load``, so a header claiming a (2^40, 3) array is a miss, not an attempt
    to allocate 24 TiB.
    """
    with zipfile.ZipFile(path) as z:
        for info in z.infolist():
            with z.open(info) as f:
                version = np.lib.format.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                else:
                    shape, _, dtype = np.lib.format.read_array_header_2_0(f)
                if (
                    dtype.hasobject
                    or np.prod(shape, dtype=object) * dtype.itemsize > info.file_size
                ):
                    return False
    return True


def _checksum(points: np.ndarray, starts: np.ndarray, key: str) -> bytes:
    h = hashlib.sha256(key.encode())
    h.update(np.ascontiguousarray(points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(starts, dtype=np.int64).tobytes())
    return h.digest()


def _valid(points: np.ndarray, starts: np.ndarray, checksum: np.ndarray, key: str) -> bool:
    """True when the arrays have the shapes and dtypes ``put`` writes and the checksum matches."""
    if points.dtype != np.float64 or points.ndim != 2 or points.shape[1] != 3:
        return False
    if starts.dtype != np.int64 or starts.ndim != 1 or len(starts) < 1:
        return False
    if checksum.dtype != np.uint8 or checksum.shape != (32,):
        return False
    if starts[0] != 0 or starts[-1] != len(points) or np.any(np.diff(starts) <= 0):
        return False
    if not np.all(np.isfinite(points)):
        return False
    return checksum.tobytes() == _checksum(points, starts, key)
