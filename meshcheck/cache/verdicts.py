"""Pair verdicts: a signed ``.json`` per pair class and setting (``verify``'s verdicts).

A verdict cannot be checked without computing it again, and a forged ``clear`` for an
interfering pair would turn a failing CI gate green: an entry is used only with a valid signature
under the run's key (see ``meshcheck.cache``), and every field is validated after it.
"""

from __future__ import annotations

import base64
import functools
import hmac
import json
import math
import os
import zlib

import numpy as np

from ..results import Location, PairVerdict, Solid, Verdict
from .store import Store, checksum, package_version

# Bump when the layout of an entry or the meaning of a verdict changes.
PAIR_FORMAT_VERSION = 4
# A pair entry's verdict is a few hundred bytes, not counting the shared solid it may carry.
MAX_PAIR_ENTRY_BYTES = 4096
# The shared solid of an interference (vertices as float64, faces as uint32, before compression)
# an entry may carry; a verdict with a larger one is not cached (it is verified again next run).
MAX_SOLID_BYTES = 8 * 2**20
# An entry file larger than this is not read: the verdict, and a solid compressed (zlib adds at
# most 0.1 % to incompressible data) then written in base64 (4/3).
MAX_PAIR_FILE_BYTES = MAX_PAIR_ENTRY_BYTES + (MAX_SOLID_BYTES * 3) // 2


def pair_key(
    a: tuple[str, np.ndarray],
    b: tuple[str, np.ndarray],
    *,
    tolerance: float,
    clearance: float | None,
    surfaces_apart: bool,
) -> str:
    """Key of a pair verdict: hex SHA-256 of everything the verdict depends on.

    A verdict is computed in its pair's own frame (``verify.classes``), from the two geometries
    placed there, so the key is the pair class's: every pair of the class, wherever it is in
    the assembly and in whichever run, finds the one verdict, and moves it to its own frame.

    Parameters
    ----------
    a, b : (str, (4, 4) float64)
        Each geometry's digest (``load.local_geometry``) and its placement in the pair's frame
        (``verify.classes.class_identity``: rounded, as given to ``verify_pair``), bit for bit.
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
    return checksum(text.encode()).hex()


@functools.cache
def verify_code_version() -> str:
    """Digest of what computes a verdict: meshcheck's version, the source of its pair classes,
    verify and depth stages, the compiled kernels' binary, and the versions of numpy, trimesh
    and manifold3d."""
    from .. import DISTRIBUTION
    from ..geometry import _kernels

    parts = [
        f"{package}={package_version(package, missing='?')};".encode()
        for package in (DISTRIBUTION, "numpy", "trimesh", "manifold3d")
    ]
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the package
    names = (
        os.path.join("verify", "classes.py"),
        os.path.join("verify", "pair.py"),
        os.path.join("verify", "depth.py"),
        "mesh.py",
        "results.py",
        os.path.join("geometry", "triangles.py"),
    )
    for path in [*(os.path.join(here, n) for n in names), _kernels.__file__]:
        try:
            with open(path, "rb") as f:
                parts.append(checksum(f.read()))
        except OSError:
            parts.append(path.encode())
    return checksum(*parts).hex()


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
        self.store = Store(self.directory, f"pairs-v{PAIR_FORMAT_VERSION}", secret=secret)

    def path(self, key: str) -> str:
        """File of the entry for ``key``: named by the key signed with the secret, so runs with
        different keys (a developer's own, CI's) keep their entries side by side instead of
        replacing each other's, and nobody without the key can tell which file is which pair's."""
        return self.store.path(self.store.sign(key.encode("ascii")).hex(), ".json")

    def get(self, key: str) -> PairVerdict | None:
        """The verdict stored for ``key``, or None when missing, unsigned or unusable.

        Returns
        -------
        verdict : PairVerdict or None
            Exactly what ``put`` stored, bit for bit (its shared solid and closest points too).
        """
        raw = self.store.read(self.path(key), MAX_PAIR_FILE_BYTES)
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
        self.store.write(self.path(key), lambda f: f.write(text))

    def remove_stale_temporaries(self) -> None:
        """Remove temporary files killed writers left (call once per run, not per entry)."""
        self.store.remove_stale_temporaries()

    def _mac(self, key: str, fields) -> str:
        text = json.dumps([key, fields], sort_keys=True, separators=(",", ":"))
        return self.store.sign(text.encode()).hex()


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
