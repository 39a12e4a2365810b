"""The C heap's free pages handed back to the system (glibc), where that pays.

Large NumPy arrays freed by a frame stay in glibc's heap (its mmap threshold rises to
32 MB as big blocks are freed), resident until ``malloc_trim`` returns them.  Returning
them lowers a large frame's peak; it also makes the next frame page-fault its arrays in
again, so callers give the free bytes below which trimming is not worth it.  Elsewhere
than glibc nothing happens.
"""

from __future__ import annotations

import ctypes

__all__ = ["free_heap_bytes", "return_freed_memory"]


class _MallInfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2`` (every field a ``size_t``)."""

    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                     "uordblks", "fordblks", "keepcost")
    ]  # fmt: skip


def _libc():
    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = _MallInfo2
    return libc


def free_heap_bytes() -> int | None:
    """Free bytes in glibc's main arena (``mallinfo2().fordblks``), None without glibc."""
    try:
        return int(_libc().mallinfo2().fordblks)
    except (OSError, AttributeError):
        return None


def return_freed_memory(above: int = 0) -> bool:
    """``malloc_trim(0)`` when more than ``above`` bytes lie free in the main arena;
    returns whether it trimmed."""
    free = free_heap_bytes()
    if free is None or free <= above:
        return False
    try:
        _libc().malloc_trim(0)
    except (OSError, AttributeError):
        return False
    return True
