"""Convex decompositions: a binary file per mesh and CoACD setting (``decompose``'s pieces).

An entry is used only when its pieces cover every triangle of the mesh (``decompose.covers``),
or when it carries a valid signature under the run's key (see ``meshcheck.cache``).
"""

from __future__ import annotations

import itertools
import json
import os
import struct

import numpy as np

from .store import Store, checksum, package_version

# Bump when the layout of an entry or the meaning of a decomposition changes (e.g. the triangle
# cover fix-up): old entries are then simply never looked up again.
FORMAT_VERSION = 3


def decomposition_key(digest: str, options: dict) -> str:
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
        "coacd": package_version("coacd"),
        "digest": digest,
        "options": options,
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return checksum(text.encode()).hex()


class DecompositionCache:
    """Convex pieces stored under ``directory``, looked up by ``decomposition_key``.

    An entry is one binary file: a fixed header (magic, point and piece counts, a SHA-256
    checksum, an HMAC-SHA256 signature or zeros), the pieces' start offsets (int64) and their
    points (float64), little-endian. The counts are checked against the file's size before
    anything else is read, so a header claiming (2^40, 3) points is a miss, not an allocation.

    Parameters
    ----------
    directory : str
        Cache root; created on the first write.
    secret : bytes, optional
        Key entries are signed with when written (``pair_secret``). ``lookup`` tells whether an
        entry carries a valid signature under it: the pipeline then trusts its pieces without
        checking that they cover the mesh, as it trusts signed pair verdicts.

    Examples
    --------
    >>> import tempfile
    >>> cache = DecompositionCache(tempfile.mkdtemp())
    >>> cache.put("ab" * 32, [np.eye(3)])
    >>> [p.tolist() for p in cache.get("ab" * 32)]
    [[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]]
    """

    MAGIC = b"MCPIECES"
    HEADER = struct.Struct("<8sQQ32s32s")  # magic, points, pieces, checksum, signature
    #: A file larger than this is not read (a decomposition is kilobytes to a few megabytes).
    MAX_BYTES = 1 << 30

    def __init__(self, directory: str, *, secret: bytes | None = None):
        self.store = Store(directory, f"decompositions-v{FORMAT_VERSION}", secret=secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``."""
        return self.store.path(key, ".bin")

    def get(self, key: str) -> list[np.ndarray] | None:
        """The pieces stored for ``key``, or None when missing or unusable.

        Returns
        -------
        pieces : list of (n_i, 3) float64, or None
            Exactly the arrays given to ``put`` (bit for bit).
        """
        hit = self.lookup(key)
        return None if hit is None else hit[0]

    def lookup(self, key: str) -> tuple[list[np.ndarray], bool] | None:
        """``(pieces, signed)`` for ``key``, or None when missing or unusable; ``signed`` is
        True when the entry's signature is valid under this cache's secret."""
        header = self.HEADER
        data = self.store.read(self.path(key), self.MAX_BYTES)
        if data is None or len(data) < header.size:
            return None
        magic, n_points, n_pieces, check, signature = header.unpack_from(data)
        if magic != self.MAGIC or len(data) != header.size + 8 * (n_pieces + 1) + 24 * n_points:
            return None
        body = data[header.size :]
        starts = np.frombuffer(body, dtype="<i8", count=n_pieces + 1)
        points = np.frombuffer(body, dtype="<f8", offset=8 * (n_pieces + 1)).reshape(-1, 3)
        signed_parts = (key.encode("ascii"), body)
        if not _valid(points, starts) or check != checksum(*signed_parts):
            return None
        signed = self.store.is_signed(signature, *signed_parts)
        points = points.astype(np.float64)  # a writable native copy
        return [points[a:b] for a, b in itertools.pairwise(starts.tolist())], signed

    def put(self, key: str, pieces: list[np.ndarray]) -> None:
        """Store ``pieces`` for ``key`` atomically, signed when the cache has a secret; a
        failure to write only costs a recompute.

        Parameters
        ----------
        key : str
            From ``decomposition_key``.
        pieces : list of (n_i, 3) float64
            Convex piece vertices, each with at least one point.
        """
        arrays = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in pieces]
        points = np.concatenate(arrays) if arrays else np.empty((0, 3))
        starts = np.concatenate([[0], np.cumsum([len(a) for a in arrays])]).astype("<i8")
        body = starts.tobytes() + np.ascontiguousarray(points, dtype="<f8").tobytes()
        signed_parts = (key.encode("ascii"), body)
        signature = self.store.sign(*signed_parts) if self.store.has_secret else bytes(32)
        head = self.HEADER.pack(
            self.MAGIC, len(points), len(arrays), checksum(*signed_parts), signature
        )
        final = self.path(key)
        self.store.write(final, lambda f: f.write(head + body))
        self.store.remove_stale_temporaries(os.path.dirname(final))


def _valid(points: np.ndarray, starts: np.ndarray) -> bool:
    """True when ``starts`` cut ``points`` into non-empty pieces and every point is finite."""
    if len(starts) < 1 or starts[0] != 0 or starts[-1] != len(points):
        return False
    return bool(np.all(np.diff(starts) > 0) and np.all(np.isfinite(points)))
