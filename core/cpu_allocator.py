"""Keep freed memory inside the process, so large CPU tensors stop costing page faults.

glibc's ``malloc`` serves every allocation above a threshold (at most 32 MB) with a fresh
``mmap`` and gives it back to the kernel on ``free``. A training step on the CPU allocates and
frees the same large tensors every time (a batch of 16 proxies at 256 px is 75 MB), so each
step pays for zero-filling and mapping them again: measured on the 2-vCPU development VM, the
synthetic data generator spends ~30% of its time on these page faults
(``benchmarks/bench_synthesis.py --no-keep-memory`` shows the difference).

:func:`keep_freed_memory` tells glibc to serve large blocks from the heap and to keep freed
memory for reuse. The process's resident size then stays at its peak instead of shrinking
between steps. It is opt-in, process-wide, and called only by long-running CPU jobs (training,
data workers, benchmarks), never by importing the library.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_MAX = -4
_NEVER_TRIM_BYTES = 2**31 - 1


def keep_freed_memory() -> bool:
    """Ask glibc to reuse freed memory instead of returning it to the kernel.

    Returns:
        True when the setting took effect (Linux with glibc); False elsewhere, where nothing
        changes.
    """
    if not sys.platform.startswith("linux"):
        return False
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (e.g. musl has no mallopt)
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    no_mmap = mallopt(_M_MMAP_MAX, 0) == 1
    no_trim = mallopt(_M_TRIM_THRESHOLD, _NEVER_TRIM_BYTES) == 1
    return no_mmap and no_trim
