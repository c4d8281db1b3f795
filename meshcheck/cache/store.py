"""One folder of cache entries, read and written safely, signed with the run's key.

Every cache (``decompositions``, ``verdicts``, ``tessellations``) keeps its entries in a
``Store``: ``DIRECTORY/NAME-vN/XX/FILE``, ``XX`` the first two characters of the file's name.

- Reading: only a regular file of at most a given size, opened without blocking and without
  following a symbolic link, in folders that are not links either (a restored CI cache can hold a
  FIFO, a device, a link or a huge file: each is a miss, never a hang or a read elsewhere).
- Writing: to a temporary file in the entry's folder, then ``os.replace``, so a reader sees a
  whole entry or none and two runs sharing the directory both succeed; a failure to write only
  costs a recompute. Temporaries a killed writer left are removed once stale.
- Signing: HMAC-SHA256 under the run's key (``pair_secret``), over an entry's parts in order;
  a plain SHA-256 (``checksum``) where an entry only guards against accidents.
- Size checks: an ``.npz`` entry's arrays are checked against the bytes they hold before numpy
  allocates them (``npz_sizes_agree``).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import hmac
import os
import stat
import tempfile
import time
import zipfile
from collections.abc import Callable
from typing import BinaryIO

import numpy as np

# A temporary file older than this was left by a writer that was killed before its os.replace.
STALE_SECONDS = 3600.0
# The environment variable that carries the key entries are signed with.
SECRET_VARIABLE = "MESHCHECK_CACHE_SECRET"


class Store:
    """The entries of one cache under ``directory``, in the folder ``name``.

    Parameters
    ----------
    directory : str or path
        Cache root, shared by every cache; created on the first write.
    name : str
        This cache's folder, with its format version (``decompositions-v3``).
    secret : bytes, optional
        The run's key (``pair_secret``): ``sign`` and ``is_signed`` use it. None: nothing is
        signed and no signature is valid.

    Examples
    --------
    >>> store = Store(tempfile.mkdtemp(), "things-v1", secret=b"k" * 32)
    >>> path = store.path("ab" * 32, ".bin")
    >>> store.write(path, lambda f: f.write(b"entry"))
    >>> store.read(path, 100)
    b'entry'
    >>> store.is_signed(store.sign(b"entry"), b"entry")
    True
    """

    def __init__(self, directory: str | os.PathLike, name: str, *, secret: bytes | None = None):
        self.root = os.path.join(os.fspath(directory), name)
        self._secret = None if secret is None else bytes(secret)

    @property
    def has_secret(self) -> bool:
        """Whether entries are signed with a key."""
        return self._secret is not None

    def path(self, name: str, suffix: str) -> str:
        """File of the entry called ``name`` (at least two characters)."""
        return os.path.join(self.root, name[:2], f"{name}{suffix}")

    def read(self, path: str, limit: int) -> bytes | None:
        """The bytes of the entry at ``path``, or None for a miss (see the module docstring)."""
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

    def write(self, path: str, write: Callable[[BinaryIO], object]) -> None:
        """Write the entry at ``path`` through ``write(file)`` atomically (see the module
        docstring); nothing is written when a folder on the way is a symbolic link."""
        folder = os.path.dirname(path)
        try:
            os.makedirs(folder, exist_ok=True)
            if not _folders_are_real(path):
                return
            suffix = os.path.splitext(path)[1]
            fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=suffix)
        except OSError:
            return
        try:
            with os.fdopen(fd, "wb") as f:
                write(f)
            os.replace(tmp, path)
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(tmp)

    def sign(self, *parts: bytes) -> bytes:
        """HMAC-SHA256 of ``parts`` (concatenated) under the key; 32 bytes."""
        if self._secret is None:
            raise ValueError("this store has no key to sign with")
        h = hmac.new(self._secret, digestmod=hashlib.sha256)
        for part in parts:
            h.update(part)
        return h.digest()

    def is_signed(self, signature: bytes, *parts: bytes) -> bool:
        """Whether ``signature`` is ``sign(*parts)`` (compared in constant time); always False
        without a key."""
        return self._secret is not None and hmac.compare_digest(signature, self.sign(*parts))

    def remove_stale_temporaries(self, folder: str | None = None) -> None:
        """Remove the temporaries killed writers left in one entry folder, or in every folder
        of this cache (once per run, not per entry)."""
        if folder is not None:
            _remove_stale_temporaries(folder)
            return
        with contextlib.suppress(OSError):
            for entry in os.scandir(self.root):
                if entry.is_dir(follow_symlinks=False):
                    _remove_stale_temporaries(entry.path)


def checksum(*parts: bytes) -> bytes:
    """SHA-256 of ``parts`` (concatenated): catches accidents, not forgeries."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    return h.digest()


def npz_sizes_agree(file) -> bool:
    """True when every array in the ``.npz`` ``file`` (a path or a binary stream) declares no
    more data than it holds, and none holds objects.

    Read before ``np.load``, so a header claiming a (2^40, 3) array is a miss, not an attempt to
    allocate 24 TiB.
    """
    with zipfile.ZipFile(file) as z:
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


@functools.cache
def package_version(package: str, missing: str = "unknown") -> str:
    """Installed version of ``package`` from its metadata (without importing it), or
    ``missing``: keys name the libraries an entry was computed with."""
    import importlib.metadata

    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return missing


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


def _remove_stale_temporaries(directory: str) -> None:
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


# ---------------------------------------------------------------------------------------------
# The run's key


def pair_secret() -> bytes | None:
    """The key entries are signed with, or None when there is no usable one.

    ``MESHCHECK_CACHE_SECRET`` when set and not empty; else the key file in the user's state
    directory, created on first use (32 random bytes, hex, mode 0600). A key file that is not
    a regular file of this user, readable or writable by others, or garbled gives None (and a
    warning): pair verdicts and tessellations are then neither read nor written.
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

        from ..errors import MeshcheckWarning

        warnings.warn(
            MeshcheckWarning(f"{path}: {exc.strerror or exc}; pair verdicts are not cached"),
            stacklevel=2,
        )
        return None


def _read_or_create_key(path: str) -> bytes:
    import secrets

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
