"""Process memory settings of a large report: freed memory given back to the system."""

from __future__ import annotations

import pyarrow as pa


def release_memory() -> None:
    """Give the memory freed after reading (Arrow's pool, the C heap) back to the system,
    so that what a large report computes next starts from what it holds, not from the
    peak of reading (a no-op where the C library cannot)."""
    import ctypes
    import gc

    gc.collect()
    pa.default_memory_pool().release_unused()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


#: Allocation size (bytes) from which the C heap maps memory of its own, given back to the
#: system when freed (glibc's ``M_MMAP_THRESHOLD``; its default grows up to 32 MiB).
MMAP_THRESHOLD = 64 * 1024


def lean_process_memory() -> None:
    """Set this process up to give freed memory back to the system as it goes: Arrow
    allocates from the C heap (its system pool) instead of a pool of its own, and the C
    heap maps blocks of :data:`MMAP_THRESHOLD` bytes or more, which it unmaps when they
    are freed. A report's steps each allocate and free working copies of many rows; with
    the defaults the freed blocks stay held, and the resident memory of a large report
    grows with the steps (``bench/bench_report.py --large N --steps``). For processes the
    command line owns (``penaltyrun-report``): it changes process-wide settings, so the
    library never calls it. A no-op for the C heap where the C library is not glibc."""
    import ctypes

    pa.set_memory_pool(pa.system_memory_pool())
    try:
        ctypes.CDLL("libc.so.6").mallopt(-3, MMAP_THRESHOLD)  # -3: M_MMAP_THRESHOLD
    except (OSError, AttributeError):  # not glibc
        pass
