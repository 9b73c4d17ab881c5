"""glibc allocator settings for the case runner's large, repeated temporaries.

A case allocates and frees arrays of tens of MB per batch of lines. With glibc's defaults
those above the mmap threshold are mapped afresh and page-faulted in on every batch, and
Dask's nanny makes it worse: it starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which
also freezes the threshold's dynamic growth, so every large array is a new mapping. Measured
on the heaviest reference case (``predict --surface sinewave2d --points 1e6 --aspect 400``,
one core): 13.6 s by default, 19.2 s with the nanny's setting, 9.7 s with these settings
(sys time 3.0 → 0.45 s). Keeping freed memory for reuse costs nothing here: a case's peak
is bounded by its batch size and stays allocated for the next batch anyway.
"""

from __future__ import annotations

import ctypes
import ctypes.util

# glibc's mallopt parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
# the largest mmap threshold glibc accepts on 64-bit (HEAP_MAX_SIZE / 2)
MMAP_THRESHOLD = 32 * 2**20
TRIM_THRESHOLD = 2**31 - 1  # keep freed memory: a worker's next batch reuses it


def tune() -> bool:
    """Apply the settings to this process; False where the C library is not glibc (the
    settings are then left to the platform's allocator)."""
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
