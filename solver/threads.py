"""The solver decides its own threading: a frame's products run on one BLAS thread.

A solve's products are small (a few hundred kilobytes: the contact fit's
columns on the sensors near the contacts, the exact member's ``C^T w``), far
too small to share between threads. OpenBLAS shares them anyway: its threads
spin while they wait, and on a 2-core machine they fight with the window's
drawing thread and with each other. Measured on three-contact frames of a
16x16 skin (2-core Xeon VM, the other core busy): 38.9 ms CPU median per
automatic solve with OpenBLAS's 2 threads, 13.0 ms on one (``docs/efficiency.md``).

:func:`one_blas_thread` sets every BLAS library the process has loaded
(numpy's and scipy's OpenBLAS, found by ``threadpoolctl``) to one thread while
a solve runs and gives back the count it found when the last solve ends. The
setting is the process's, not the thread's (OpenBLAS has no per-thread
count): solves on several threads at once share one setting, and a large
product on another thread during a solve runs on one thread too. Set-ups
(factorizations of large skins) are not wrapped: they gain from every core.
The machine's ``OPENBLAS_NUM_THREADS`` and the like are never touched.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager

__all__ = ["one_blas_thread"]

_lock = threading.Lock()
_libraries = None   # threadpoolctl's controllers of the BLAS libraries loaded
_depth = 0          # solves running now, on any thread
_saved: list[int] = []


def _blas():
    global _libraries
    if _libraries is None:
        # imported here: threadpoolctl inspects the loaded libraries, so after numpy and scipy
        from threadpoolctl import ThreadpoolController

        _libraries = ThreadpoolController().select(user_api="blas").lib_controllers
    return _libraries


@contextmanager
def one_blas_thread():
    """Run the block with every BLAS library on one thread (module notes); reentrant and thread-safe.

    Costs about 16 us per outermost entry and exit (two OpenBLAS libraries,
    measured); nested and concurrent blocks cost nothing more.
    """
    global _depth, _saved
    with _lock:
        if _depth == 0:
            libraries = _blas()
            _saved = [library.get_num_threads() for library in libraries]
            for library, count in zip(libraries, _saved, strict=True):
                if count != 1:
                    library.set_num_threads(1)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                for library, count in zip(_blas(), _saved, strict=True):
                    if count != 1:
                        library.set_num_threads(count)
