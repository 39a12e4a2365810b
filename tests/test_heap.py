"""hwsim.core.heap: the heap's free bytes read from glibc, a trim only above the floor."""

from __future__ import annotations

import platform

import numpy as np
import pytest

from hwsim.core.heap import free_heap_bytes, return_freed_memory

glibc = pytest.mark.skipif(
    platform.libc_ver()[0] != "glibc", reason="mallinfo2/malloc_trim are glibc's"
)


@glibc
def test_freed_arrays_show_as_free_heap_and_a_trim_returns_them() -> None:
    # Many 1 MB arrays freed: below glibc's mmap threshold once it has risen, or served by
    # mmap before; either way the trim must report what it did consistently.
    arrays = [np.ones(1 << 17) for _ in range(64)]
    del arrays
    before = free_heap_bytes()
    assert isinstance(before, int) and before >= 0
    assert return_freed_memory(above=before + (1 << 40)) is False  # floor not reached
    trimmed = return_freed_memory(above=-1)  # any free byte: trims
    assert trimmed is True
    assert free_heap_bytes() <= before + (1 << 20)
