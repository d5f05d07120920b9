"""The solver decides its own threading: a frame's products run on one BLAS thread.

A solve's products are small (a few hundred kilobytes: the contact fit's
columns on the sensors near the contacts, the exact member's ``C^T w``), far
too small to share between threads. OpenBLAS shares them anyway: its threads
spin while they wait, and on a 2-core machine they fight with the window's
drawing thread and with each other. Measured on three-contact frames of a
16x16 skin (2-core VM, the other core busy): 38.9 ms CPU median per
automatic solve with OpenBLAS's 2 threads, 13.0 ms on one.

:func:`one_blas_thread` puts the calling thread's BLAS calls on one thread
while a solve runs and gives back its count after. OpenBLAS (0.3.27 and
later, as numpy's and scipy's wheels carry it) keeps that count per thread
(``openblas_set_num_threads_local``): other threads, a factorization of a
large skin among them, keep every core. A BLAS library without a per-thread
count (found by ``threadpoolctl``) is left as it is: its process-wide count
is not the solver's to change (and OpenBLAS ignores a process-wide change
from a worker thread once the main thread has made one, measured). The
machine's ``OPENBLAS_NUM_THREADS`` and the like are never touched.
"""

from __future__ import annotations

import ctypes
import threading
from contextlib import contextmanager

__all__ = ["one_blas_thread", "local_libraries"]

_lock = threading.Lock()
_local = None   # each BLAS library's per-thread setter, found once


def local_libraries() -> list:
    """The per-thread thread-count setters of the BLAS libraries loaded (``int f(int)``, returning
    the count it replaces); empty when none has one."""
    global _local
    with _lock:
        if _local is None:
            # imported here: threadpoolctl inspects the libraries loaded, so after numpy and scipy
            from threadpoolctl import ThreadpoolController

            found = []
            for library in ThreadpoolController().select(user_api="blas").lib_controllers:
                setter = getattr(library.dynlib, "openblas_set_num_threads_local", None)
                if setter is not None:
                    setter.restype, setter.argtypes = ctypes.c_int, [ctypes.c_int]
                    found.append(setter)
            _local = found
        return _local


@contextmanager
def one_blas_thread():
    """Run the block's BLAS calls on one thread (module notes): this thread only, nested blocks
    too; the count before is given back on the way out, an exception included.

    Costs about 5 us per block (two OpenBLAS libraries, measured).
    """
    setters = local_libraries()
    before = [setter(1) for setter in setters]
    try:
        yield
    finally:
        for setter, count in zip(setters, before, strict=True):
            setter(count)
