"""Models read before, kept in kinegen's cache and verified like a compiled library.

Reading a model is SymPy's work: every expression parsed, the drivers' time functions derived,
the masses and forces checked (the excavator ~0.4-0.6 s in every process that reads it, against
~0.1 s to load it kept). The same bytes read under the same name by the same kinegen give the
same model, so :func:`kept_model` keeps it (:mod:`pickle`, with the warnings reading it gave) in
``$KINEGEN_CACHE/models`` under the SHA-256 of the bytes, the name and kinegen's code
fingerprint (its sources, SymPy's and SymEngine's versions: :func:`kinegen.textcache.code_fingerprint`)
and gives the warnings again on a hit.

Trust: loading a pickle runs code, so the kept bytes are recorded in the trust store
(:mod:`kinegen.integrity`) as they are written, and a file whose bytes the store does not know --
planted, edited, truncated -- is never loaded: the model is read again and kept anew. A model
that fails to read keeps nothing (its error is raised again each time), and a cache that cannot
be read or written costs the reading, never the model.
"""

from __future__ import annotations

import hashlib
import pickle
import warnings
from collections.abc import Callable
from pathlib import Path

from kinegen.files import cache_folder
from kinegen.integrity import keep_file, trusted_file
from kinegen.model.schema import Model
from kinegen.textcache import code_fingerprint, given_and_recorded


def _path(data: bytes, file: str) -> Path:
    # (the bytes' digest and the fingerprint have fixed lengths: no other bytes and name give the same key text)
    parts = [b"model", hashlib.sha256(data).digest(), code_fingerprint().encode(), file.encode("utf-8", "surrogatepass")]
    key = hashlib.sha256(b"\0".join(parts)).hexdigest()
    return cache_folder() / "models" / key[:2] / f"{key}.pickle"


def kept_model(data: bytes, file: str, read: Callable[[], Model]) -> Model:
    """The model of the bytes ``data`` read under the name ``file``: kept from an earlier
    ``read()`` of the same bytes and name by this kinegen when the trust store knows the kept
    bytes (its warnings given again), else ``read()`` and kept."""
    path = _path(data, file)
    stored = trusted_file(path)
    if stored is not None:
        try:
            model, said = pickle.loads(stored)  # bytes kinegen wrote: the trust store knows them
        except Exception:  # a kept file that does not load is read again, whatever it raised
            model, said = None, None
        if isinstance(model, Model) and isinstance(said, list):
            for category, message in said:
                warnings.warn(message, category, stacklevel=3)
            return model
    model, caught = given_and_recorded(read)
    try:
        kept = pickle.dumps((model, [(w.category, str(w.message)) for w in caught]), protocol=5)
    except (pickle.PicklingError, TypeError, AttributeError, RecursionError):
        return model
    keep_file(path, kept)
    return model
