"""Compiled kernels (numba): floats and arrays only.

numba's on-disk cache (``cache=True``) checks only the source file of the cached function, not
the files of the functions it calls, and the kernels here call across files (e.g. the
low-thrust loop calls the steering laws, the closed loops call the integrator). On import this
package therefore hashes its own sources and, when they changed since the cache was written,
removes the cached machine code under its ``__pycache__`` directories so every kernel is
recompiled from the current sources once. (With ``NUMBA_CACHE_DIR`` set the cache lives
elsewhere and is not checked.)
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

logger = logging.getLogger(__name__)

_STAMP = "numba_sources.sha256"


def _drop_stale_numba_cache(root: Path) -> None:
    """Delete numba cache files under ``root`` when the package sources changed."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    stamp = root / "__pycache__" / _STAMP
    current = digest.hexdigest()
    try:
        if stamp.is_file() and stamp.read_text() == current:
            return
        for cache_dir in root.rglob("__pycache__"):
            for pattern in ("*.nbi", "*.nbc"):
                for path in cache_dir.glob(pattern):
                    path.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(current)
        logger.debug("dynamics sources changed: numba cache cleared")
    except OSError as exc:  # read-only install: numba falls back to its own cache dir
        logger.debug("numba cache check skipped: %s", exc)


_drop_stale_numba_cache(Path(__file__).parent)
