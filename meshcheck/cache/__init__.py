"""Content-addressed stores: one signed store, and the decompositions, pair verdicts and STEP
tessellations kept in it.

- ``store``: where entries live and how they are read, written, signed and size-checked
  (``Store``), and the run's key (``pair_secret``);
- ``decompositions``: convex pieces, a binary file per mesh and CoACD setting
  (``DecompositionCache``, ``decomposition_key``);
- ``verdicts``: pair verdicts, a ``.json`` per part pair, placement and setting (``PairCache``,
  ``pair_key``); the B-rep stage keeps its verdicts there too;
- ``tessellations``: tessellated STEP files, an ``.npz`` per file content and setting
  (``TessellationCache``, ``tessellation_key``).

A run opens them once (``open_caches``: the directory, the key read once) and the pipeline hands
each stage the one it uses.

Modelled on black's ``src/black/cache.py``: a plain directory (the user's cache directory by
default, any directory CI can persist), entries named by a key built from the content's hash, the
settings, the versions of the libraries that computed them and the entry's format version.
Entries are written to a temporary file in the same directory and moved into place with
``os.replace``, so a reader sees a whole entry or none, and two runs sharing the directory at once
both succeed (the last writer wins with an identical entry). Entries are plain arrays behind a
fixed header, JSON, or ``.npz`` read without pickles; an entry that is truncated, garbled, of the
wrong sizes, or whose checksum or signature does not match counts as a miss and is rewritten.

Trust: the cache is input from outside like any mesh (CI restores it from an artifact store). A
decomposition's checksum is plain SHA-256 of public data, so anyone can forge an entry; the
checksum only catches accidents. What keeps a forged entry from changing a verdict is that the
pipeline uses a decomposition only after checking that its pieces cover every triangle of the mesh
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

A tessellation is the parts' geometry, as unverifiable as a verdict: its entries are signed too.

meshcheck signs, and keeps the key out of the cache directory: ``MESHCHECK_CACHE_SECRET`` when set
(in CI, from the CI's secret store: a workflow run from a fork gets no secrets, so it can neither
use nor poison signed entries), else a random key created once with mode 0600 in the user's state
directory (``platformdirs.user_state_dir``, never inside a cache directory), refused when others
can read or write it. A cache restored on a fresh CI machine without the secret therefore yields
decompositions (checked on their own, see above) but no pair verdicts or tessellations: they are
computed again and signed with the new key. Every field of an entry is validated after the
signature, and the key of an entry covers everything the verdict depends on (``pair_key``), so a
genuine entry is never applied to another pair. What is left to trust is the key holder, as for
any CI secret.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from .decompositions import DecompositionCache, decomposition_key
from .store import SECRET_VARIABLE, Store, pair_secret
from .tessellations import Tessellation, TessellationCache, tessellation_key
from .verdicts import PairCache, pair_key

__all__ = [
    "SECRET_VARIABLE",
    "Caches",
    "DecompositionCache",
    "PairCache",
    "Store",
    "Tessellation",
    "TessellationCache",
    "decomposition_key",
    "open_caches",
    "pair_key",
    "pair_secret",
    "tessellation_key",
]


@dataclass(frozen=True)
class Caches:
    """The caches of one run, each None when it is not used.

    Attributes
    ----------
    decompositions : DecompositionCache or None
        Signed with the run's key when there is one; unsigned entries are checked against their
        mesh before use.
    verdicts : PairCache or None
        Mesh and B-rep pair verdicts; only with a key.
    tessellations : TessellationCache or None
        Tessellated STEP files; only with a key.
    """

    decompositions: DecompositionCache | None = None
    verdicts: PairCache | None = None
    tessellations: TessellationCache | None = None


def open_caches(cache_dir: str | os.PathLike | None) -> Caches:
    """The run's caches under ``cache_dir``, signed with the run's key (``pair_secret``, read
    here, once); no cache at all when ``cache_dir`` is None.

    Examples
    --------
    >>> open_caches(None)
    Caches(decompositions=None, verdicts=None, tessellations=None)
    """
    if cache_dir is None:
        return Caches()
    directory = os.fspath(cache_dir)
    secret = pair_secret()
    if secret is None:
        return Caches(DecompositionCache(directory))
    return Caches(
        DecompositionCache(directory, secret=secret),
        PairCache(directory, secret=secret),
        TessellationCache(directory, secret=secret),
    )
