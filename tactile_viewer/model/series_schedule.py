"""The time plots' schedule: which series to solve in the background, when, and what is kept. No Qt.

The time-plot dock (:class:`tactile_viewer.qt.time_plots.TimePlotsDock`) keeps
its widgets, the Qt timers that call this and the drawing; this decides:

- what the series must be of: the model's recording, its solver and its
  parameters (None: automatic);
- one series solved at a time, in a background task
  (:func:`~tactile_viewer.model.series_solving.compute_series`): a new one
  cancels the one running, and results of older ones are dropped (each
  series asked for has its own generation);
- what is cached: the complete series of the last :data:`CACHED` parameters
  of a source and solver (Auto on and off again costs nothing), forgotten with
  a new source, another solver or a re-tare (same file, other stresses);
- a hidden dock solves nothing: its series is stale, and solved when shown;
- the partial series the solving thread hands over, each handed on once, and
  a live source's rolling window of the frames solved so far.
"""

from __future__ import annotations

from collections import OrderedDict

from .series import Series
from .series_solving import MAX_FRAMES, SeriesBuilder, compute_series, spread_frames
from .solved import Solved
from .worker import Cancelled

__all__ = ["SeriesSchedule", "CACHED"]

CACHED = 4  # series kept per source and solver (Auto on and off again costs nothing)


class SeriesSchedule:
    """Which series of the model's recording is solved, when; the complete ones kept.

    Parameters
    ----------
    model : ViewerModel
        Read only: its recording, solver (``reconstructor``), parameters
        (``auto``, ``shear_ratio``, ``shear_direction``), ``path``, ``live``
        and ``is_open``.
    background : callable
        ``background(work, done, failed) -> task``: runs ``work(progress)``
        away from the caller and calls ``done(series)`` or ``failed(exc)``
        back on the caller's thread; the task has ``cancel()``.
    finished : callable
        ``finished(series)``: a complete series of what was asked (solved, or
        from the cache).
    failed : callable
        ``failed(exc)``: the series asked for could not be solved (not called
        for a cancelled or superseded one).
    max_frames : int, optional
        Frames a series solves at most, evenly over the recording.
    every : float, optional
        Seconds between the partial series the solving thread hands over.
    cached : int, optional
        Complete series kept per source and solver. Default :data:`CACHED`.

    Attributes
    ----------
    task : object or None
        The background task solving the series asked for (None: none).
    stale : bool
        The series asked for was not solved because the dock was hidden.
    live : SeriesBuilder or None
        The rows of a live source's frames solved so far (None: not live).
    """

    def __init__(self, model, background, *, finished, failed, max_frames: int = MAX_FRAMES,
                 every: float = 0.3, cached: int = CACHED):
        spread_frames(0, max_frames)  # checks max_frames and names it
        self.model = model
        self.max_frames = int(max_frames)
        self.every = every
        self.cached = cached
        self._background = background
        self._finished = finished
        self._failed = failed
        self._generation = 0  # grows with each series asked for: results of older ones are dropped
        self.task = None
        self._partial = [None]  # the newest partial series, handed over by the solving thread
        self._drawn_partial = None
        self.stale = False  # the series shown is not of what the model shows now
        self._asked = None  # what the series being solved (or shown) is of
        self._cache: OrderedDict = OrderedDict()  # parameters -> complete series of the source and solver
        self.live: SeriesBuilder | None = None
        self._live_dirty = False

    @property
    def solving(self) -> bool:
        """A series is being solved."""
        return self.task is not None

    def wanted(self) -> tuple:
        """``(recording, solver, parameters)``: what the series must be of now (parameters None: Auto)."""
        model = self.model
        parameters = None if model.auto else (model.shear_ratio, model.shear_direction)
        return model.recording, model.reconstructor, parameters

    def asked_for(self, recording) -> bool:
        """The series asked for (being solved or shown) is of ``recording``."""
        return self._asked is not None and self._asked[0] is recording

    def start(self, *, visible: bool = True) -> int | None:
        """Solve the series the model wants, in the background; the number of frames it solves.

        None when nothing is solved: nothing open, a hidden dock (:attr:`stale`
        until shown) or a series in the cache (handed to ``finished`` at once).
        """
        self.cancel()
        model = self.model
        if model.recording is None or model.reconstructor is None:
            return None
        wanted = self.wanted()
        recording, solver, parameters = wanted
        self._asked = wanted
        if not visible:
            self.stale = True  # solved when the dock is shown: a hidden dock costs nothing
            return None
        self.stale = False
        if parameters in self._cache:
            self._cache.move_to_end(parameters)
            self._finished(self._cache[parameters])
            return None
        self._generation += 1
        generation = self._generation
        frames = spread_frames(len(recording), self.max_frames)
        given = {} if parameters is None else dict(shear_ratio=parameters[0], shear_direction=parameters[1])
        box = self._partial = [None]
        source = str(model.path) if model.path is not None else recording.description
        every = self.every

        def work(progress):
            # on the task's thread: only reads the recording and the solver (series_solving.py says why it
            # may)
            return compute_series(recording, solver, frames=frames, progress=progress, every=every,
                                  partial=lambda series: box.__setitem__(0, series), source=source, **given)

        self.task = self._background(work, lambda series: self._done(generation, series),
                                     lambda exc: self._fail(generation, exc))
        return len(frames)

    def cancel(self) -> None:
        """Drop the series being solved; its thread stops after the frame it is solving."""
        self._generation += 1
        if self.task is not None:
            self.task.cancel()
            self.task = None
        self._partial = [None]

    def new_source(self) -> None:
        """A new source, or the same one with another solver (kernel, quality): all of it again."""
        self._cache.clear()
        self.cancel()
        self.live = None

    def follow_live(self, grid, *, kernel: str, source: str, span: float) -> Series:
        """Collect a live source's frames as they are solved (the last ``span`` seconds); its empty series."""
        self.live = SeriesBuilder(grid, kernel=kernel, mode="as shown", source=source, span=span)
        self._asked = None
        return self.live.series()

    def parameters_changed(self) -> bool:
        """New parameters: the series of the old ones is dropped at once (the window's own solves need
        the processor during a drag); True when the new ones' series is to be solved once they settle."""
        if self.model.live or not self.model.is_open:
            return False
        self.cancel()
        return True

    def solved(self, solved: Solved) -> bool:
        """The model solved a frame: a live one joins the rolling window; True when the series must be
        solved again (the recording was re-tared: same file, other stresses)."""
        if self.live is not None:
            if self.model.live:
                self.live.add(solved)
                self._live_dirty = True
            return False
        asked = self._asked
        if asked is not None and self.model.recording is not asked[0]:
            self._cache.clear()
            return True
        return False

    def new_partial(self) -> Series | None:
        """The newest partial series the solving thread handed over, once (None: none new)."""
        partial = self._partial[0]
        if partial is None or partial is self._drawn_partial:
            return None
        self._drawn_partial = partial
        return partial

    def new_live_series(self) -> Series | None:
        """The live frames as a series when some came since the last look (None: none came)."""
        if self.live is None or not self._live_dirty:
            return None
        self._live_dirty = False
        return self.live.series()

    def _done(self, generation: int, series: Series):
        if generation != self._generation:
            return
        self.task = None
        parameters = self._asked[2]
        self._cache[parameters] = series
        while len(self._cache) > self.cached:
            self._cache.popitem(last=False)
        self._finished(series)

    def _fail(self, generation: int, exc: BaseException):
        if generation != self._generation or isinstance(exc, Cancelled):
            return
        self.task = None
        self._failed(exc)
