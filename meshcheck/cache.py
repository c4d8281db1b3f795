"""Content-addressed stores: convex decompositions (a binary file per mesh and setting) and pair
verdicts (``.json`` per part pair, placement and setting).

Modelled on black's ``src/black/cache.py``: a plain directory (the user's cache directory by
default, any directory CI can persist), entries named by a key built from the mesh's content hash,
the decomposition settings, the CoACD version and this file's format version. Entries are written
to a temporary file in the same directory and moved into place with ``os.replace``, so a reader sees
a whole entry or none, and two runs sharing the directory at once both succeed (the last writer
wins with an identical entry). Entries are plain arrays behind a fixed header, never pickles; an
entry that is truncated, garbled, of the wrong sizes, or whose checksum does not match counts as a
miss and is rewritten.

Trust: the cache is input from outside like any mesh (CI restores it from an artifact store), and
its checksum is plain SHA-256 of public data, so anyone can forge an entry. The checksum only
catches accidents. What keeps a forged entry from changing a verdict is that the pipeline uses a
decomposition only after checking that its pieces cover every triangle of the mesh
(``decompose.covers``); a forged or stale entry that does not is recomputed. Pieces that cover the
mesh but are too big only cost time: the verify stage decides every pair they let through. An
entry that also carries a valid signature under the run's key (below) was written by a run
holding the key, from pieces that covered the mesh then, so it is used without the check (which
costs Qhull on every piece, most of a warm run's decomposition stage).

Pair verdicts (``PairCache``) are a different matter: a verdict cannot be checked without
computing it again, and a forged ``clear`` for an interfering pair would turn a failing CI gate
green, the one defect meshcheck must never have. What each way of trusting them buys:

- Checking entries against the pieces (use a cached ``clear`` only when the convex pieces already
  prove the pair clear) saves only the cheap pairs; the pairs whose surfaces come near, where the
  8 ms go, would be verified every time.
- Caching only verdicts that cannot hide a clash (``interference``) leaves every clear pair to be
  verified again: no incremental re-check at all.
- A secret key that signs entries (HMAC-SHA256) makes a forged entry a miss, for anyone who does
  not hold the key. It is worth exactly as much as the key is kept apart from the entries: a key
  file inside the cache directory would travel with the directory (a CI cache restored from a
  shared store carries it), so whoever can write the store could read the key and sign.

meshcheck signs, and keeps the key out of the cache directory: ``MESHCHECK_CACHE_SECRET`` when set
(in CI, from the CI's secret store: a workflow run from a fork gets no secrets, so it can neither
use nor poison signed entries), else a random key created once with mode 0600 in the user's state
directory (``platformdirs.user_state_dir``, never inside a cache directory), refused when others
can read or write it. A cache restored on a fresh CI machine without the secret therefore yields
decompositions (checked on their own, see above) but no pair verdicts: they are computed again and
signed with the new key. Every field of an entry is validated after the signature, and the key of
an entry covers everything the verdict depends on (``pair_key``), so a genuine entry is never
applied to another pair. What is left to trust is the key holder, as for any CI secret.
"""

from __future__ import annotations

import base64
import contextlib
import functools
import hashlib
import hmac
import itertools
import json
import math
import os
import stat
import struct
import tempfile
import zlib

import numpy as np

from .results import Location, PairVerdict, Solid, Verdict

# Bump when the layout of an entry or the meaning of a decomposition changes (e.g. the triangle
# cover fix-up): old entries are then simply never looked up again.
FORMAT_VERSION = 3
# The same for pair verdict entries.
PAIR_FORMAT_VERSION = 3
# A pair entry's verdict is a few hundred bytes, not counting the shared solid it may carry.
MAX_PAIR_ENTRY_BYTES = 4096
# The shared solid of an interference (vertices as float64, faces as uint32, before compression)
# an entry may carry; a verdict with a larger one is not cached (it is verified again next run).
MAX_SOLID_BYTES = 8 * 2**20
# An entry file larger than this is not read: the verdict, and a solid compressed (zlib adds at
# most 0.1 % to incompressible data) then written in base64 (4/3).
MAX_PAIR_FILE_BYTES = MAX_PAIR_ENTRY_BYTES + (MAX_SOLID_BYTES * 3) // 2
# The environment variable that carries the key pair verdicts are signed with.
SECRET_VARIABLE = "MESHCHECK_CACHE_SECRET"


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
        self.root = os.path.join(os.fspath(directory), f"decompositions-v{FORMAT_VERSION}")
        self._secret = None if secret is None else bytes(secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``."""
        return os.path.join(self.root, key[:2], f"{key}.bin")

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
        data = read_entry(self.path(key), self.MAX_BYTES)
        if data is None or len(data) < header.size:
            return None
        magic, n_points, n_pieces, checksum, signature = header.unpack_from(data)
        if magic != self.MAGIC or len(data) != header.size + 8 * (n_pieces + 1) + 24 * n_points:
            return None
        body = data[header.size :]
        starts = np.frombuffer(body, dtype="<i8", count=n_pieces + 1)
        points = np.frombuffer(body, dtype="<f8", offset=8 * (n_pieces + 1)).reshape(-1, 3)
        if not _valid(points, starts) or not hmac.compare_digest(
            checksum, _digest(hashlib.sha256(), key, body)
        ):
            return None
        signed = self._secret is not None and hmac.compare_digest(
            signature, _digest(hmac.new(self._secret, digestmod=hashlib.sha256), key, body)
        )
        points = points.astype(np.float64)  # a writable native copy
        return [points[a:b] for a, b in itertools.pairwise(starts.tolist())], signed

    def put(self, key: str, pieces: list[np.ndarray]) -> None:
        """Store ``pieces`` for ``key`` atomically, signed when the cache has a secret; a
        failure to write only costs a recompute.

        Parameters
        ----------
        key : str
            From ``cache_key``.
        pieces : list of (n_i, 3) float64
            Convex piece vertices, each with at least one point.
        """
        arrays = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in pieces]
        points = np.concatenate(arrays) if arrays else np.empty((0, 3))
        starts = np.concatenate([[0], np.cumsum([len(a) for a in arrays])]).astype("<i8")
        body = starts.tobytes() + np.ascontiguousarray(points, dtype="<f8").tobytes()
        checksum = _digest(hashlib.sha256(), key, body)
        signature = bytes(32)
        if self._secret is not None:
            signature = _digest(hmac.new(self._secret, digestmod=hashlib.sha256), key, body)
        head = self.HEADER.pack(self.MAGIC, len(points), len(arrays), checksum, signature)
        final = self.path(key)
        write_atomically(final, ".bin", lambda f: f.write(head + body))
        _remove_stale_temporaries(os.path.dirname(final))


def _digest(h, key: str, body: bytes) -> bytes:
    """``h`` (a SHA-256 or HMAC-SHA256) over an entry's key and body."""
    h.update(key.encode("ascii"))
    h.update(body)
    return h.digest()


def _valid(points: np.ndarray, starts: np.ndarray) -> bool:
    """True when ``starts`` cut ``points`` into non-empty pieces and every point is finite."""
    if len(starts) < 1 or starts[0] != 0 or starts[-1] != len(points):
        return False
    return bool(np.all(np.diff(starts) > 0) and np.all(np.isfinite(points)))


# A temporary file older than this was left by a writer that was killed before its os.replace.
STALE_SECONDS = 3600.0


def read_entry(path: str, limit: int) -> bytes | None:
    """The bytes of the cache entry at ``path`` (``ROOT/XX/NAME``), or None for a miss.

    Only a regular file of at most ``limit`` bytes is read, opened without blocking and without
    following a symbolic link, in folders that are not symbolic links either: a FIFO, a device,
    a link or an oversized file (a restored CI cache can hold any of them) is a miss, never a
    hang or a read outside the cache.
    """
    if not _folders_are_real(path):
        return None
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_BINARY", 0))
    except OSError:
        return None
    try:
        with os.fdopen(fd, "rb") as f:
            info = os.fstat(f.fileno())
            if not stat.S_ISREG(info.st_mode) or info.st_size > limit:
                return None
            data = f.read(limit + 1)
    except (OSError, ValueError):
        return None
    return data if len(data) == info.st_size else None


def _folders_are_real(path: str) -> bool:
    """True when the two folders above an entry (the cache's ``NAME-vN`` and ``XX``) are real
    directories, not symbolic links (which would lead reads, writes and clean-ups elsewhere)."""
    sub = os.path.dirname(path)
    for folder in (os.path.dirname(sub), sub):
        try:
            if not stat.S_ISDIR(os.lstat(folder).st_mode):
                return False
        except OSError:
            return False
    return True


def write_atomically(final: str, suffix: str, write) -> None:
    """Write an entry at ``final`` (``ROOT/XX/NAME``) through ``write(file)`` to a temporary file
    in the same directory, then ``os.replace`` it into place: readers see a whole entry or none.
    Nothing is written when a folder on the way is a symbolic link. A failure to write only
    costs a recompute."""
    try:
        os.makedirs(os.path.dirname(final), exist_ok=True)
        if not _folders_are_real(final):
            return
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(final), prefix=".tmp-", suffix=suffix)
    except OSError:
        return
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, final)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _remove_stale_temporaries(directory: str) -> None:
    import time

    cutoff = time.time() - STALE_SECONDS
    if not _folders_are_real(os.path.join(directory, "entry")):
        return  # never clean up through a symbolic link, outside the cache
    with contextlib.suppress(OSError):
        for entry in os.scandir(directory):
            if (
                entry.name.startswith(".tmp-")
                and entry.is_file(follow_symlinks=False)
                and entry.stat(follow_symlinks=False).st_mtime < cutoff
            ):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _sizes_agree(path: str) -> bool:
    """True when every array in the ``.npz`` at ``path`` declares no more data than it holds.

    Read before ``np.load``, so a header claiming a (2^40, 3) array is a miss, not an attempt
    to allocate 24 TiB.
    """
    import zipfile

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


# ---------------------------------------------------------------------------------------------
# Pair verdicts


def pair_key(
    a: tuple[str, np.ndarray],
    b: tuple[str, np.ndarray],
    *,
    tolerance: float,
    clearance: float | None,
    surfaces_apart: bool,
) -> str:
    """Key of a pair verdict: hex SHA-256 of everything the verdict depends on.

    Parameters
    ----------
    a, b : (str, (4, 4) float64)
        Each part's mesh digest (frame-local geometry) and its transform to world coordinates.
        Both transforms go in bit for bit, which fixes b in a's frame exactly, and also where
        the pair is: a verdict is not reused for a pair moved as a whole, because rounding at
        other coordinates can change a verdict at the edge of the tolerance, and the verdict's
        location is in world coordinates.
    tolerance, clearance : float
        The pair's touching tolerance and the clearance, model units (bit for bit).
    surfaces_apart : bool
        The convex pieces proved the surfaces beyond reach (``verify_pair``'s argument).

    Returns
    -------
    key : str
        64 hex characters; it also covers the pair format, meshcheck's version and verify
        sources, and the versions of the libraries a verdict is computed with.
    """

    def placed(part):
        digest, transform = part
        matrix = np.ascontiguousarray(transform, dtype=np.float64).reshape(4, 4)
        return [str(digest), matrix.tobytes().hex()]

    payload = {
        "format": PAIR_FORMAT_VERSION,
        "code": verify_code_version(),
        "a": placed(a),
        "b": placed(b),
        "tolerance": float(tolerance).hex(),
        "clearance": None if clearance is None else float(clearance).hex(),
        "surfaces_apart": bool(surfaces_apart),
    }
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@functools.cache
def verify_code_version() -> str:
    """Digest of what computes a verdict: meshcheck's version, the source of its verify and depth
    stages, the compiled kernels' binary, and the versions of numpy, trimesh and manifold3d."""
    import importlib.metadata

    from . import DISTRIBUTION
    from .geometry import _kernels

    h = hashlib.sha256()
    for package in (DISTRIBUTION, "numpy", "trimesh", "manifold3d"):
        try:
            h.update(f"{package}={importlib.metadata.version(package)};".encode())
        except importlib.metadata.PackageNotFoundError:
            h.update(f"{package}=?;".encode())
    here = os.path.dirname(os.path.abspath(__file__))
    names = (
        os.path.join("verify", "pair.py"),
        os.path.join("verify", "depth.py"),
        "mesh.py",
        "results.py",
        os.path.join("geometry", "triangles.py"),
    )
    for path in [*(os.path.join(here, n) for n in names), _kernels.__file__]:
        try:
            with open(path, "rb") as f:
                h.update(hashlib.sha256(f.read()).digest())
        except OSError:
            h.update(path.encode())
    return h.hexdigest()


def pair_secret() -> bytes | None:
    """The key pair verdicts are signed with, or None when there is no usable one.

    ``MESHCHECK_CACHE_SECRET`` when set and not empty; else the key file in the user's state
    directory, created on first use (32 random bytes, hex, mode 0600). A key file that is not
    a regular file of this user, readable or writable by others, or garbled gives None (and a
    warning): pair verdicts are then neither read nor written.
    """
    value = os.environ.get(SECRET_VARIABLE)
    if value:
        return hashlib.sha256(value.encode("utf-8", "surrogateescape")).digest()
    import platformdirs

    path = os.path.join(platformdirs.user_state_dir("meshcheck"), "cache-secret")
    try:
        return _read_or_create_key(path)
    except OSError as exc:
        import warnings

        from .errors import MeshcheckWarning

        warnings.warn(
            MeshcheckWarning(f"{path}: {exc.strerror or exc}; pair verdicts are not cached"),
            stacklevel=2,
        )
        return None


def _read_or_create_key(path: str) -> bytes:
    import errno
    import secrets
    import stat

    if not os.path.lexists(path):
        os.makedirs(os.path.dirname(path), mode=0o700, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-")  # mode 0600
        try:
            with os.fdopen(fd, "w") as f:
                f.write(secrets.token_hex(32))
            with contextlib.suppress(FileExistsError):  # another run made one first: use it
                os.link(tmp, path)
        finally:
            os.unlink(tmp)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_size > 256:
            raise OSError(errno.EINVAL, "the cache key file is not a small regular file")
        if hasattr(os, "getuid") and (info.st_uid != os.getuid() or info.st_mode & 0o077):
            raise OSError(errno.EPERM, "the cache key file is not private (owner only, 0600)")
        text = os.read(fd, 256).decode("ascii", "replace").strip()
    finally:
        os.close(fd)
    if len(text) != 64 or any(c not in "0123456789abcdef" for c in text):
        raise OSError(errno.EINVAL, "the cache key file is garbled")
    return bytes.fromhex(text)


class PairCache:
    """Pair verdicts stored under ``directory``, looked up by ``pair_key``, signed with a secret.

    Parameters
    ----------
    directory : str
        Cache root (the decomposition cache's); created on the first write.
    secret : bytes
        Key of the entries' HMAC-SHA256 (``pair_secret``); an entry signed with another key
        is a miss.

    Examples
    --------
    >>> import tempfile
    >>> cache = PairCache(tempfile.mkdtemp(), secret=b"k" * 32)
    >>> verdict = PairVerdict(Verdict.TOUCHING, 0.0)
    >>> cache.put("ab" * 32, verdict)
    >>> cache.get("ab" * 32) == verdict
    True
    >>> PairCache(cache.directory, secret=b"x" * 32).get("ab" * 32) is None
    True
    """

    def __init__(self, directory: str, *, secret: bytes):
        self.directory = os.fspath(directory)
        self.root = os.path.join(self.directory, f"pairs-v{PAIR_FORMAT_VERSION}")
        self._secret = bytes(secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``: named by the key signed with the secret, so runs with
        different keys (a developer's own, CI's) keep their entries side by side instead of
        replacing each other's, and nobody without the key can tell which file is which pair's."""
        name = hmac.new(self._secret, key.encode("ascii"), hashlib.sha256).hexdigest()
        return os.path.join(self.root, name[:2], f"{name}.json")

    def get(self, key: str) -> PairVerdict | None:
        """The verdict stored for ``key``, or None when missing, unsigned or unusable.

        Returns
        -------
        verdict : PairVerdict or None
            Exactly what ``put`` stored, bit for bit (its shared solid and closest points too).
        """
        raw = read_entry(self.path(key), MAX_PAIR_FILE_BYTES)
        try:
            entry = json.loads(raw) if raw is not None else None
        except (ValueError, RecursionError):
            return None
        if not isinstance(entry, dict) or set(entry) != {"key", "verdict", "mac"}:
            return None
        mac = entry["mac"]
        if entry["key"] != key or not isinstance(mac, str) or not mac.isascii():
            return None
        if not hmac.compare_digest(mac, self._mac(key, entry["verdict"])):
            return None
        return _decode_verdict(entry["verdict"])

    def put(self, key: str, verdict: PairVerdict) -> None:
        """Store ``verdict`` atomically, signed; one whose solid is over ``MAX_SOLID_BYTES`` is
        not stored."""
        fields = _encode_verdict(verdict)
        if fields is None:
            return
        entry = {"key": key, "verdict": fields, "mac": self._mac(key, fields)}
        text = json.dumps(entry, sort_keys=True, separators=(",", ":")).encode("ascii")
        write_atomically(self.path(key), ".json", lambda f: f.write(text))

    def remove_stale_temporaries(self) -> None:
        """Remove temporary files killed writers left (call once per run, not per entry)."""
        with contextlib.suppress(OSError):
            for entry in os.scandir(self.root):
                if entry.is_dir(follow_symlinks=False):
                    _remove_stale_temporaries(entry.path)

    def _mac(self, key: str, fields) -> str:
        text = json.dumps([key, fields], sort_keys=True, separators=(",", ":"))
        return hmac.new(self._secret, text.encode(), hashlib.sha256).hexdigest()


# ---------------------------------------------------------------------------------------------
# The one encoding of a verdict (``results.PairVerdict``) in an entry


def _encode_verdict(v: PairVerdict) -> dict | None:
    """The JSON fields of a verdict: floats as exact hex, the solid as compressed base64; None
    when its solid is over ``MAX_SOLID_BYTES``."""

    def number(x):
        return None if x is None else float(x).hex()

    def points(ps):
        return [[float(c).hex() for c in np.asarray(p, dtype=np.float64)] for p in ps]

    where = v.location
    solid = None
    if v.solid is not None:
        solid = _encode_solid(v.solid)
        if solid is None:
            return None
    return {
        "status": str(v.status),
        "distance": number(v.distance),
        "depth": number(v.depth),
        "volume": number(v.volume),
        "location": None if where is None else points((where.centroid, where.lower, where.upper)),
        "surface_only": bool(v.is_surface_only),
        "closest": None if v.closest is None else points(v.closest),
        "solid": solid,
    }


def _encode_solid(solid: Solid) -> dict | None:
    vertices = np.ascontiguousarray(solid.vertices, dtype="<f8")
    faces = np.ascontiguousarray(solid.faces, dtype="<u4")
    raw = vertices.tobytes() + faces.tobytes()
    if len(raw) > MAX_SOLID_BYTES or len(vertices) > np.iinfo(np.uint32).max:
        return None
    data = base64.b64encode(zlib.compress(raw, 6)).decode("ascii")
    return {"vertices": len(vertices), "faces": len(faces), "data": data}


_FIELDS = {
    "status", "distance", "depth", "volume", "location", "surface_only", "closest", "solid"
}  # fmt: skip


def _decode_verdict(fields) -> PairVerdict | None:
    """The verdict of a signed entry, or None when any field is out of its domain."""
    if not isinstance(fields, dict) or set(fields) != _FIELDS:
        return None
    try:
        if not isinstance(fields["surface_only"], bool):
            return None
        location = _points(fields["location"], 3)
        closest = _points(fields["closest"], 2)
        return PairVerdict(
            Verdict(fields["status"]),
            _number(fields["distance"], infinite=True),
            depth=_number(fields["depth"], optional=True),
            volume=_number(fields["volume"], optional=True),
            location=None if location is None else Location(*location),
            is_surface_only=fields["surface_only"],
            solid=_decode_solid(fields["solid"]),
            closest=closest,
        )
    except (ValueError, OverflowError, TypeError, zlib.error):
        return None


def _number(x, *, optional: bool = False, infinite: bool = False) -> float | None:
    """A length or volume from its hex text: not NaN, not negative, finite unless ``infinite``."""
    if x is None and optional:
        return None
    if not isinstance(x, str) or len(x) > 40:
        raise ValueError
    value = float.fromhex(x)
    if math.isnan(value) or value < 0 or (math.isinf(value) and not infinite):
        raise ValueError
    return value


def _points(value, count: int) -> tuple[np.ndarray, ...] | None:
    """``count`` finite (3,) float64 points from hex text; None stays None."""
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != count:
        raise ValueError
    out = []
    for p in value:
        if not isinstance(p, list) or len(p) != 3 or not all(isinstance(c, str) for c in p):
            raise ValueError
        xyz = np.array([float.fromhex(c) for c in p], dtype=np.float64)
        if not np.all(np.isfinite(xyz)):
            raise ValueError
        out.append(xyz)
    return tuple(out)


def _decode_solid(value) -> Solid | None:
    """A solid from its entry fields: sizes checked before and after inflating, finite
    vertices, faces that index them."""
    if value is None:
        return None
    if not isinstance(value, dict) or set(value) != {"vertices", "faces", "data"}:
        raise ValueError
    n, m, data = value["vertices"], value["faces"], value["data"]
    if not all(type(k) is int and k > 0 for k in (n, m)) or not isinstance(data, str):
        raise ValueError
    size = 24 * n + 12 * m
    if size > MAX_SOLID_BYTES:
        raise ValueError
    inflate = zlib.decompressobj()
    raw = inflate.decompress(base64.b64decode(data, validate=True), size + 1)
    if len(raw) != size or not inflate.eof or inflate.unused_data:
        raise ValueError
    vertices = np.frombuffer(raw, dtype="<f8", count=3 * n).reshape(n, 3).astype(np.float64)
    faces = np.frombuffer(raw, dtype="<u4", offset=24 * n).reshape(m, 3).astype(np.int64)
    if not np.all(np.isfinite(vertices)) or faces.max() >= n:
        raise ValueError
    return Solid(vertices, faces)
