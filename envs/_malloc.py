"""glibc malloc settings that keep long runs from growing.

Every environment makes a few allocations of 13-18 MB: MuJoCo's model
buffer (17.5 MB in MuJoBan, mostly textures) and mjData's arena (13-14 MB),
plus Mesa's copies of the textures when cameras are on. glibc serves blocks
above ``M_MMAP_THRESHOLD`` (128 KiB at start) with ``mmap`` and gives them
back to the system on ``free``, but the first such ``free`` raises the
threshold to the freed block's size (glibc's dynamic threshold, up to 32 MiB):
from then on the blocks of every rebuilt environment come from the heap, the
old ones leave holes there that glibc cannot return, and resident memory
grew in steps at every rebuild (+274 MB over 900 episodes of
``benchmarks/soak.py``; results/soak_before_fix.json).

`apply()` (run when ``envs`` is imported) fixes the threshold with
``mallopt(M_MMAP_THRESHOLD, 128 KiB)``, which per mallopt(3) also switches
the dynamic adjustment off. That would leave the heap's trim threshold at
128 KiB too, and glibc would then give the top of the heap back and fault
it in again at every control step of the board games (~300 page faults per
MuJoGo step); so `apply` also sets ``M_TRIM_THRESHOLD`` to 32 MiB, the
dynamic scheme's order of magnitude. `trim()` (run by
``Environment.close``) calls ``malloc_trim(0)`` to hand free heap pages
back. None of this changes what any program computes, only where glibc
puts memory. It does nothing on a C library without these functions, and
`apply` leaves glibc alone when the user has chosen a threshold
(``MALLOC_MMAP_THRESHOLD_``/``MALLOC_TRIM_THRESHOLD_`` or
``glibc.malloc.mmap_threshold``/``trim_threshold`` in ``GLIBC_TUNABLES``).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

#: mallopt(3) parameter numbers (malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: The mmap threshold we fix: glibc's own starting value (128 KiB).
MMAP_THRESHOLD = 128 * 1024
#: Free memory at the top of the heap kept rather than given back at once.
TRIM_THRESHOLD = 32 * 2**20

_libc = None
_applied = False


def _load_libc():
    global _libc
    if _libc is None:
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            libc.mallopt  # noqa: B018  (glibc has both; others may not)
            libc.malloc_trim  # noqa: B018
        except (OSError, AttributeError):
            libc = False
        _libc = libc
    return _libc or None


def user_chose_threshold() -> bool:
    """Whether the environment already sets glibc's mmap or trim threshold."""
    tunables = os.environ.get("GLIBC_TUNABLES", "")
    return (
        "MALLOC_MMAP_THRESHOLD_" in os.environ
        or "MALLOC_TRIM_THRESHOLD_" in os.environ
        or "glibc.malloc.mmap_threshold" in tunables
        or "glibc.malloc.trim_threshold" in tunables
    )


def apply() -> bool:
    """Fixes glibc's mmap threshold at `MMAP_THRESHOLD` and its trim threshold
    at `TRIM_THRESHOLD`; True if it did."""
    global _applied
    libc = _load_libc()
    if libc is None or user_chose_threshold():
        return False
    _applied = bool(
        libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
        and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
    return _applied


def applied() -> bool:
    """Whether `apply` has fixed the threshold in this process."""
    return _applied


_MALLINFO2_FIELDS = (
    "arena",
    "ordblks",
    "smblks",
    "hblks",
    "hblkhd",
    "usmblks",
    "fsmblks",
    "uordblks",
    "fordblks",
    "keepcost",
)


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in _MALLINFO2_FIELDS]


def mallinfo() -> dict[str, int] | None:
    """glibc's ``mallinfo2()`` as a dict of byte counts (``arena``: obtained
    for the heap; ``uordblks``/``fordblks``: in use/free there; ``hblkhd``:
    in mmapped blocks), or None without it."""
    libc = _load_libc()
    info = getattr(libc, "mallinfo2", None) if libc is not None else None
    if info is None:
        return None
    info.restype = _Mallinfo2
    m = info()
    return {name: getattr(m, name) for name in _MALLINFO2_FIELDS}


def trim() -> None:
    """Returns the free memory of the heap to the system (``malloc_trim(0)``)."""
    libc = _load_libc()
    if libc is not None:
        libc.malloc_trim(0)
