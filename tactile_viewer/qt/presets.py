"""The quality presets of the geometry shown, measured in the background.

Each preset is a point of the speed/accuracy front measured on this very
geometry (:func:`measurement.tradeoff.preset_front`): its cost per frame and
its median error are what the quality box says. Measuring builds every
configuration, so it runs in a separate process, only for skins where that
takes seconds, and once per geometry.
"""

from __future__ import annotations

import multiprocessing

from PyQt6 import QtCore

from measurement import tradeoff

from ..model.viewer_model import ViewerModel
from ..model.worker import Cancelled
from .parameters_panel import ParametersPanel
from .tasks import TaskRunner

__all__ = ["PresetMeasurer", "PRESET_LIMIT"]

PRESET_LIMIT = 32 * 32  # skins whose quality presets are measured automatically


def describe(m: tradeoff.Measurement) -> str:
    """A preset's measured cost and error, for the quality box."""
    return f"{m.name}, {m.frame_ms:.2f} ms/frame, error {100 * tradeoff.error_of(m):.1f}% of |F|"


class PresetMeasurer(QtCore.QObject):
    """Measures the shown geometry's presets once it has settled and offers them in the quality box.

    Signals
    -------
    measured()
        The presets of the shown geometry are in the quality box.
    """

    measured = QtCore.pyqtSignal()

    def __init__(self, model: ViewerModel, panel: ParametersPanel, tasks: TaskRunner, *, notify, parent=None):
        super().__init__(parent)
        self.model, self.panel, self.tasks, self._notify = model, panel, tasks, notify
        self._fronts: dict = {}  # geometry key -> its measured presets
        self._measuring = None  # the key being measured
        self._offered = None  # the key whose presets the box offers
        model.recording_changed.connect(self._on_source)

    def _on_source(self):
        # the box offers the shown geometry's presets only; unmeasured ones come once things settle
        key = self.model.grid.key
        if key == self._offered:
            return  # the same geometry with another kernel or preset: the box stays as chosen
        self._offered = key
        self.panel.set_presets(self._fronts.get(key, {}), describe)
        if key not in self._fronts:
            # after the first frames are drawn: measuring takes a core for a few seconds
            QtCore.QTimer.singleShot(1000, self._measure_if_shown)

    def _measure_if_shown(self):
        # measuring builds every configuration, full ones included: keep it to skins where that
        # takes seconds (tactile-tradeoff measures larger ones from the command line)
        window = self.parent()
        if (window is not None and window.isVisible() and not self.tasks.closed and self.model.is_open
                and self.model.grid.size <= PRESET_LIMIT):
            self.measure()

    def measure(self):
        """Measure the front of the shown geometry in the background; emits ``measured`` when offered."""
        grid = self.model.grid
        key = grid.key
        if key in self._fronts:
            self.panel.set_presets(self._fronts[key], describe)
            self.measured.emit()
            return
        if self._measuring == key:
            return  # measured comes when it is done
        self._measuring = key

        def work(progress):
            # In another process: measuring takes seconds of Python, which in this process would
            # take the interpreter lock from the solve thread and slow every slider move.
            with multiprocessing.get_context("spawn").Pool(1) as pool:
                pending = pool.apply_async(tradeoff.preset_front, (grid,))
                while True:
                    try:
                        return pending.get(timeout=0.1)
                    except multiprocessing.TimeoutError:
                        if not progress(0, 0):  # the window closed: leaving the block ends the process
                            raise Cancelled("presets not measured: the window closed") from None

        def done(chosen):
            self._fronts[key] = chosen
            self._measuring = None
            if self.model.is_open and self.model.grid.key == key:  # not another geometry by now
                self.panel.set_presets(chosen, describe)
                self.measured.emit()

        def failed(exc):
            self._measuring = None
            if not isinstance(exc, Cancelled):
                self._notify(f"could not measure presets: {exc}")

        self.tasks.background(work, done, failed)
