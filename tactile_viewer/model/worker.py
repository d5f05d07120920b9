"""A latest-wins worker thread: runs the newest job submitted; jobs it did not reach are dropped.

No Qt here: the viewer's model owns one and hands results back through the
``dispatch`` function it was given (the Qt layer's posts to the GUI thread).
A solve takes milliseconds while frames and slider moves come faster, so
solving every request would only queue up latency; solving the newest keeps
the screen at most one solve behind.
"""

from __future__ import annotations

import sys
import threading

__all__ = ["LatestWorker", "Cancelled"]


class Cancelled(Exception):
    """Work stopped because it was asked to (the user cancelled, the window closed); nothing was written."""


class LatestWorker:
    """One thread running ``run(job)`` for the newest submitted job.

    ``run`` reports its own outcome (the model's job posts its result or its
    error); an exception escaping it goes to ``threading.excepthook`` (the
    app's error reporter) and the worker keeps running.

    Attributes
    ----------
    done : int
        Jobs run.
    dropped : int
        Jobs replaced by a newer one before they started.
    """

    def __init__(self, run, *, name: str = "worker"):
        self._run = run
        self._condition = threading.Condition()
        self._pending = None
        self._busy = False
        self._closed = False
        self.done = 0
        self.dropped = 0
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    def submit(self, job) -> None:
        """Run ``job`` next, in place of any job still waiting."""
        with self._condition:
            if self._closed:
                raise RuntimeError("the worker is closed")
            if self._pending is not None:
                self.dropped += 1
            self._pending = job
            self._condition.notify_all()

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until nothing is waiting or running; False on timeout."""
        with self._condition:
            return self._condition.wait_for(lambda: self._pending is None and not self._busy, timeout)

    @property
    def busy(self) -> bool:
        """A job is waiting or running."""
        with self._condition:
            return self._pending is not None or self._busy

    def close(self, timeout: float = 10.0) -> None:
        """Drop what is waiting, let the running job finish, end the thread."""
        with self._condition:
            self._closed = True
            self._pending = None
            self._condition.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout)

    def _loop(self):
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                job, self._pending = self._pending, None
                self._busy = True
            try:
                self._run(job)
            except Exception:
                # the job reports its own errors; this is a bug in the job itself: report it
                # like any uncaught thread error, and keep serving
                threading.excepthook(threading.ExceptHookArgs((*sys.exc_info(), self._thread)))
            finally:
                with self._condition:
                    self._busy = False
                    self.done += 1
                    self._condition.notify_all()

