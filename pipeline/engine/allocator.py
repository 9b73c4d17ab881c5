"""Allocator settings for the case runner's large, repeated temporaries: glibc's, and
numpy's advice to the kernel about huge pages.

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
import os

# glibc's mallopt parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
# the largest mmap threshold glibc accepts on 64-bit (HEAP_MAX_SIZE / 2)
MMAP_THRESHOLD = 32 * 2**20
TRIM_THRESHOLD = 2**31 - 1  # keep freed memory: a worker's next batch reuses it

# numpy advises the kernel to back every array of 4 MiB and more with huge pages
# (madvise(MADV_HUGEPAGE)). Where the kernel compacts memory at the fault to find one
# (transparent_hugepage/defrag "madvise", this project's machines), a fresh array's first touch
# is ~5x slower, and the huge pages did not come (AnonHugePages stayed 0 kB): 224 MB filled in
# 0.34 s against 0.07 s without the advice; the 990k-point chord spiral, whose 28 M dense
# samples are fresh arrays, 3.8 -> 2.9 s (sys 1.24 -> 0.32 s). The kernels stream through
# their arrays, so fewer TLB misses would gain little. A user's own NUMPY_MADVISE_HUGEPAGE wins.
HUGEPAGE_ENV = "NUMPY_MADVISE_HUGEPAGE"


def no_hugepage_advice() -> None:
    """Stop numpy's huge-page advice in this process and the processes it starts (workers),
    unless the user set ``NUMPY_MADVISE_HUGEPAGE``. numpy reads the variable when it is
    imported, and has no public switch after that: a process that imported numpy before (a
    notebook) keeps the advice, while the command line (which calls this before numpy loads)
    and a sweep's workers (started with this environment) run without it."""
    if os.environ.get(HUGEPAGE_ENV) is None:
        os.environ[HUGEPAGE_ENV] = "0"


def tune() -> bool:
    """Apply the settings to this process (:func:`no_hugepage_advice`, then glibc's); False
    where the C library is not glibc (its settings are then left to the platform's
    allocator)."""
    no_hugepage_advice()
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
