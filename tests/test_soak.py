"""Issue 16: resident memory must not grow over many environment rebuilds.

The growth came from glibc's dynamic mmap threshold: once a large mmapped
block (MuJoCo's 13-18 MB model buffers and mjData arenas) is freed, glibc
serves the next ones from the heap, which fragments and never shrinks.
`envs._malloc` fixes the threshold (and raises the trim threshold, so
that the fixed one does not make the heap churn) when ``envs`` is imported and
``Environment.close`` trims the heap. These tests run in fresh interpreters
so that no earlier test has moved the threshold.
"""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux") or not hasattr(ctypes.CDLL(None), "mallinfo2"),
    reason="glibc malloc (mallinfo2) only",
)

# Allocates a block of MuJoBan's model-buffer size twice (freeing the first)
# and reports whether each was mmapped (glibc's mallinfo2.hblkhd grows).
PROBE = r"""
import ctypes, json, sys
if sys.argv[1] == "envs":
    import envs
libc = ctypes.CDLL("libc.so.6")
class M(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks "
                 "keepcost").split()]
libc.mallinfo2.restype = M
libc.malloc.restype = ctypes.c_void_p
libc.free.argtypes = [ctypes.c_void_p]
# 4 MB of 64 KiB blocks at the top of the heap, freed: is the heap given back?
blocks = [libc.malloc(64 * 1024) for _ in range(64)]
grown = libc.mallinfo2().arena
for block in reversed(blocks):
    libc.free(block)
kept_top = libc.mallinfo2().arena >= grown
size = 17 * 2**20 + 12345
mmapped = []
for _ in range(2):
    before = libc.mallinfo2().hblkhd
    block = libc.malloc(size)
    mmapped.append(libc.mallinfo2().hblkhd - before >= size)
    libc.free(block)
applied = None
if sys.argv[1] == "envs":
    applied = envs._malloc.applied()
print(json.dumps({"mmapped": mmapped, "kept_top": kept_top, "applied": applied}))
"""


def _environ_without_malloc_settings(**env) -> dict:
    environ = {
        k: v
        for k, v in os.environ.items()
        if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")
    }
    environ.update(env)
    return environ


def probe(mode: str, **env) -> dict:
    environ = _environ_without_malloc_settings(**env)
    out = subprocess.run(
        [sys.executable, "-c", PROBE, mode],
        cwd=ROOT,
        env=environ,
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_without_envs_glibc_moves_large_blocks_to_the_heap_after_the_first_free():
    # The mechanism behind the growth: this is what importing envs prevents.
    assert probe("plain")["mmapped"] == [True, False]


def test_importing_envs_fixes_the_mmap_threshold():
    result = probe("envs")
    assert result["applied"] is True
    assert result["mmapped"] == [True, True]


def test_importing_envs_keeps_the_top_of_the_heap_between_steps():
    # A fixed mmap threshold alone also fixes glibc's trim threshold at
    # 128 KiB: the heap's top would be given back and faulted in again at
    # every step (~300 page faults per MuJoGo step). envs raises it.
    assert probe("plain")["kept_top"] is False  # glibc's own 128 KiB to start with
    assert probe("envs")["kept_top"] is True


def test_a_threshold_chosen_by_the_user_is_left_alone():
    result = probe("envs", MALLOC_MMAP_THRESHOLD_=str(64 * 2**20))
    assert result["applied"] is False
    assert result["mmapped"] == [False, False]  # the user's 64 MiB threshold
    assert probe("envs", MALLOC_TRIM_THRESHOLD_=str(2**20))["applied"] is False


# Rebuilds MuJoBan environments the way long runs do (close one, build the
# next, eight times) and reports how far malloc's heap
# (mallinfo2.arena: bytes obtained with brk or in arena heaps) grew.
REBUILD = r"""
import gc, json
import envs
env = envs.load("mujoban/level1", seed=0, **envs.no_cameras("mujoban/level1"))
env.reset()
heaps = []
for i in range(8):
    env.close()
    env = envs.load("mujoban/level1", seed=i + 1, **envs.no_cameras("mujoban/level1"))
    env.reset()
    gc.collect()
    heaps.append(envs._malloc.mallinfo()["arena"])
print(json.dumps({"heap_mb": [h / 2**20 for h in heaps]}))
"""


@pytest.mark.slow
def test_rebuilding_environments_keeps_their_large_blocks_out_of_the_heap():
    out = subprocess.run(
        [sys.executable, "-c", REBUILD],
        cwd=ROOT,
        env=_environ_without_malloc_settings(),
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    heap_mb = json.loads(out.stdout.strip().splitlines()[-1])["heap_mb"]
    # Each MuJoBan model buffer is 17.5 MB; none of them may end up in the heap.
    assert max(heap_mb) - heap_mb[0] < 10, heap_mb


def test_close_trims_the_heap_once(monkeypatch):
    import envs
    from envs import _malloc

    calls = []
    monkeypatch.setattr(_malloc, "trim", lambda: calls.append(1))
    env = envs.load("mujoxo/mixture", seed=0, **envs.no_cameras("mujoxo/mixture"))
    env.reset()
    env.close()
    env.close()  # idempotent: nothing more to free
    assert calls == [1]
