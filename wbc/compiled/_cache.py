"""Keep numba's on-disk cache honest across modules.

numba keys a cached function on its own source file only: a kernel that calls functions of
another module (a tick calling the row and QP kernels, the rows reading the layout constants)
would keep running the *old* code of those after they change (an upgrade, an edit in a
development checkout). :func:`refresh` stamps each kernel's cache with a digest of the files
it depends on and flushes the cache when they changed.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path


def digest(files: Sequence[str | os.PathLike]) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(Path(f).read_bytes())
    return h.hexdigest()


def refresh(dispatchers: Sequence[object], depends_on: Sequence[str | os.PathLike]) -> None:
    """Flush the on-disk cache of every dispatcher whose dependencies changed since it was
    cached (best effort: a cache directory that cannot be written is left alone)."""
    stamp_value = digest(depends_on)
    for d in dispatchers:
        cache = getattr(d, "_cache", None)
        path = getattr(cache, "cache_path", None)
        if not path:
            continue
        name = f"{d.py_func.__module__}.{d.py_func.__qualname__}.deps"
        stamp = Path(path) / name
        try:
            if stamp.exists() and stamp.read_text() == stamp_value:
                continue
            cache.flush()
            os.makedirs(path, exist_ok=True)
            stamp.write_text(stamp_value)
        except OSError:
            continue
