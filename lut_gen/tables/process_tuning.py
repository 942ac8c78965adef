"""The process's settings for a bake: glibc's heap kept and OpenBLAS on one thread while the
bake runs, put back after (Linux with glibc and numpy's OpenBLAS; elsewhere each is a no-op).

Measured on the default bake (one process each, 2 cores, 2026-12-04):

* **The heap.** The bake allocates and frees temporaries of 1-32 MB thousands of times on its
  worker threads. With glibc's defaults those go back to the kernel as they are freed (mmap
  below the dynamic threshold's slow rise, trimming of the threads' arenas), and every reuse
  faults its pages in again: 0.83 M page faults and 12.7 s of system time for 30.7 s of user
  time, 25.5 s in all. Keeping freed memory for the bake's length (an mmap threshold of 32 MB,
  glibc's own ceiling for its dynamic threshold, and no trimming) cut the faults to 0.16 M and
  the bake to 19.3 s. After the bake the trim threshold goes to 64 MB (twice the mmap threshold,
  as glibc's dynamic rule sets it) and malloc_trim hands the freed memory back, so Blender does
  not keep the bake's 1.2 GB peak.
* **OpenBLAS threads.** The bake's row stages already run on a thread per core
  (bake_parallel.parallel_rows); OpenBLAS's own threads inside their matmuls only compete with them,
  so those stages run OpenBLAS on one thread. The big matmuls of the orders' sphere
  integrals, outside them, keep its threads (one thread there made each order 10-40% slower).
"""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import threading

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 2**20
TRIM_DURING_BAKE = 2**31 - 1   # (mallopt takes an int) no trimming while baking
TRIM_AFTER_BAKE = 2 * MMAP_THRESHOLD

def cores() -> int:
    """The cores this process may run on (a farm worker pinned to some sees only those)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):           # not Linux
        return max(os.cpu_count() or 1, 1)


_lock = threading.Lock()
_active = 0
_blas_threads_before = None


def _glibc():
    """The C library when it is glibc (it has mallopt and malloc_trim), else None."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        libc.gnu_get_libc_version          # glibc only (musl, macOS and Windows lack it)
        libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
        libc.malloc_trim.argtypes = (ctypes.c_size_t,)
        return libc
    except (OSError, AttributeError, TypeError):
        return None


def _openblas():
    """(get, set) of the thread count of the OpenBLAS numpy loaded, or None (another BLAS, or
    not found). numpy's wheels name its symbols with a "64_" suffix."""
    try:
        with open("/proc/self/maps") as maps:
            paths = sorted({line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line})
    except OSError:
        return None
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for suffix in ("64_", ""):
            get = getattr(lib, f"openblas_get_num_threads{suffix}", None)
            set_ = getattr(lib, f"openblas_set_num_threads{suffix}", None)
            if get is not None and set_ is not None:
                set_.argtypes = (ctypes.c_int,)
                return get, set_
    return None


_LIBC = _glibc()
_BLAS = None            # found on first use: numpy must have loaded it


@contextlib.contextmanager
def tuned_for_bake():
    """glibc's heap kept while the block runs (nested and concurrent bakes: the last one out
    trims)."""
    global _active
    with _lock:
        _active += 1
        if _active == 1 and _LIBC is not None:
            _LIBC.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
            _LIBC.mallopt(M_TRIM_THRESHOLD, TRIM_DURING_BAKE)
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0 and _LIBC is not None:
                _LIBC.mallopt(M_TRIM_THRESHOLD, TRIM_AFTER_BAKE)
                _LIBC.malloc_trim(0)


_blas_users = 0


@contextlib.contextmanager
def blas_on_one_thread():
    """OpenBLAS on one thread while the block runs: for stages that already run a thread per
    core (the big matmuls between them keep OpenBLAS's threads)."""
    global _BLAS, _blas_users, _blas_threads_before
    with _lock:
        if _BLAS is None:
            _BLAS = _openblas() or ()
        _blas_users += 1
        if _blas_users == 1 and _BLAS:
            _blas_threads_before = _BLAS[0]()
            _BLAS[1](1)
    try:
        yield
    finally:
        with _lock:
            _blas_users -= 1
            if _blas_users == 0 and _BLAS and _blas_threads_before:
                _BLAS[1](_blas_threads_before)
