"""The C heap's release policy: keep freed memory for the next temporary instead of handing it
back to the kernel after each one (glibc's malloc; elsewhere nothing is changed).

Why: numpy takes each array's memory from malloc. By default glibc serves blocks above its mmap
threshold (128 kB at the start, raised up to 32 MB as such blocks are freed) by fresh mappings,
and returns the top of its heap to the kernel once more than the trim threshold (twice that) lies
free there. A loop that makes and drops arrays of megabytes at every step, as the terrain-aided
navigator's ray march does (60 000-250 000 points a call, a dozen temporaries each), then gets
fresh pages every time, and the kernel faults in and zeroes each of them: on F (2026-12-03) a
120 s tan_radalt_300m run took 4.4 million page faults and 11 s of system time in 37 s of wall
time. With the thresholds below, 51 000 faults and 0.4 s, a wall time of 25-27 s, the same
record bit for bit and the peak resident memory 332 MB against 327 MB (docs/measurements.md,
"The C heap's release policy"). Either threshold alone does not do it: a high mmap threshold
still trims the freed blocks off the heap's top, and a high trim threshold alone fixes the mmap
threshold at its 128 kB start (glibc stops adapting it once either is set).

The cost is memory the process keeps: up to TRIM_THRESHOLD_BYTES of freed heap that the kernel
could otherwise have had back (the peaks measured moved by 1-6 %). A threshold the user set in
the environment (MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_, or glibc.malloc tunables in
GLIBC_TUNABLES) is left as they set it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import platform

log = logging.getLogger(__name__)

# Arrays up to this size come from the heap, not from a mapping of their own: a 1920 x 1080 x 3
# float64 frame is 50 MB.
MMAP_THRESHOLD_BYTES = 64 * 2**20
# Free memory at the heap's top kept for reuse before any is returned to the kernel.
TRIM_THRESHOLD_BYTES = 256 * 2**20

_M_TRIM_THRESHOLD = -1  # glibc malloc.h
_M_MMAP_THRESHOLD = -3
_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds for this process (once; forked children inherit
    them). Returns whether they are set: False where the C library is not glibc, where the
    user set their own, or where glibc refused a value."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    env = os.environ
    if env.get("MALLOC_MMAP_THRESHOLD_") or env.get("MALLOC_TRIM_THRESHOLD_") or "malloc." in env.get("GLIBC_TUNABLES", ""):
        log.debug("heap: the environment sets glibc's malloc; thresholds left as they are")
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        ok = libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
        ok = ok and libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
    except (OSError, AttributeError) as exc:
        log.debug("heap: glibc's mallopt not reached (%s)", exc)
        return False
    _applied = bool(ok)
    if not ok:
        log.debug("heap: glibc refused the malloc thresholds")
    return _applied
