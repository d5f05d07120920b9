"""The time plots: a dock of pyqtgraph plots of the whole recording, with a cursor at the frame drawn.

Stacked plots with one time axis: total normal force, size and direction of
the total tangential force, their ratio, and the contact centroid's x and y;
when the recording carries its true forces, the truth beside the estimate
and two rows of errors. A vertical cursor on every plot stands at the frame
drawn and follows playback; a click on a plot (or dragging the cursor) shows
the nearest frame. CSV (:meth:`tactile_viewer.model.series.Series.to_csv`) and PNG
exports.

Contacts followed over time: when the series holds more than one contact
identity (:attr:`tactile_viewer.model.series.Series.contacts`), every row also has a
thin curve per contact, named ``#1``, ``#2`` ... in the Fz legend as in the
contacts table, broken where the contact is absent (the ``MAX_CONTACT_CURVES``
contacts present on the most frames; a single contact's curves would repeat
the totals, so none are drawn for it).

The series is solved in the background (:func:`tactile_viewer.model.series.compute_series`
in a task of the window's :class:`~tactile_viewer.qt.tasks.TaskRunner`, without
its modal dialog: the window stays free) and drawn as it fills in; a new
source, kernel, quality or parameters cancel it and start again (parameter
changes after a short pause, so a slider drag starts one series, not fifty).
A live source has no whole recording: the dock draws the frames solved so far,
the last ``live_span`` seconds of them. During playback only the cursor moves:
the curves are drawn when the series changes, never per frame.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pyqtgraph as pg  # takes the Qt binding already imported (the window's PyQt6), else PyQt6 first
from PyQt6 import QtCore, QtGui, QtWidgets

from solver.arguments import MAX_STRESS
from solver.checks import real_number

from ..io.recording import written_whole
from ..io.sidecar import derived_name
from ..model.series import MAX_FRAMES, Series, SeriesBuilder, compute_series, nearest_frame, spread_frames
from ..model.viewer_model import ViewerModel
from ..model.worker import Cancelled
from .preferences import save_rows, saved_rows
from .tasks import TaskRunner

__all__ = ["TimePlotsDock", "ROWS", "ERROR_ROWS"]

REFRESH_MS = 300  # partial series and live frames reach the curves this often
CURSOR_WAIT_MS = 100  # the cursor's lines wait this long for the frame's result before moving alone
SETTLE_MS = 250  # parameters must stay this long before their series is solved (a slider drag)
LIVE_SPAN_S = 60.0  # a live source's plots hold this much of its history
ROW_PX = 50  # the least height of one plot: below it the dock scrolls instead of squashing them
AXIS_PX = 35  # the time axis under the lowest plot shown
# the rows shown at first: three plots and the time axis fit the dock's first height at 1280x800
# (all eight rows did not: 2.3 of them showed, and no time axis); the Rows button shows the others,
# the errors against a recording's truth among them
FIRST_ROWS = ("fz", "tangential", "direction")
CACHED = 4  # series kept per source and solver (Auto on and off again costs nothing)
MAX_CONTACT_CURVES = 8  # contacts drawn with curves of their own (those present on the most frames)

# (key, axis label, unit, the plotted value of a Quantities) of each row; the labels are short: a
# row is a few centimetres high and its label runs along its side (the tooltips spell them out)
ROWS = (
    ("fz", "Fz", "mN", lambda q: q.fz * 1e3),
    ("tangential", "|Ft|", "mN", lambda q: q.tangential * 1e3),
    ("direction", "dir", "deg", lambda q: np.degrees(q.direction)),
    ("shear_ratio", "|Ft|/Fz", "", lambda q: q.shear_ratio),
    ("centroid_x", "x", "mm", lambda q: q.centroid_x * 1e3),
    ("centroid_y", "y", "mm", lambda q: q.centroid_y * 1e3),
)
# (key, axis label, unit, ((curve name, the plotted value of a TruthErrors), ...)): with truth only
ERROR_ROWS = (
    ("error", "error", "%", (("Fz, % of |Fz*|", lambda e: e.normal * 100),
                             ("Ft, % of |F*|", lambda e: e.tangential * 100))),
    ("direction_error", "dir err", "deg", (("Ft direction", lambda e: e.direction_deg),)),
)
TIPS = {
    "fz": "Total normal force (sum of Fz over the nodes), mN",
    "tangential": "Size of the total tangential force |sum (Fx, Fy)|, mN",
    "direction": "Direction of the total tangential force, degrees from +x (none where there is no shear)",
    "shear_ratio": "Total tangential over total normal force",
    "centroid_x": "x of the contact centroid (where the compressive load is centred), mm",
    "centroid_y": "y of the contact centroid, mm",
    "error": "Errors against the truth: total Fz in % of the true Fz; total tangential force in % of the "
             "true |F|",
    "direction_error": "Angle between the estimated and the true total tangential force, degrees",
}
ANGLE_TICKS = [[(v, str(v)) for v in (-180, -90, 0, 90, 180)]]

# on white, as the scene: the plots read alike on screen, in the PNG export and in print
ESTIMATE_PEN = pg.mkPen((31, 119, 180), width=2)
LOST_BRUSH = pg.mkBrush(176, 0, 32, 50)  # the NO DATA red, faint
TRUTH_PEN = pg.mkPen((255, 127, 14), width=2, style=QtCore.Qt.PenStyle.DashLine)
ERROR_PENS = (pg.mkPen((214, 39, 40), width=2), pg.mkPen((44, 160, 44), width=2))
# one colour per contact identity (cycling), none of them the estimate's, the truth's or the errors'
CONTACT_COLOURS = ((148, 103, 189), (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34),
                   (23, 190, 207), (44, 160, 44), (214, 39, 40))
CURSOR_PEN = pg.mkPen((0, 0, 0, 170), width=1)
CURSOR_HOVER_PEN = pg.mkPen((214, 39, 40), width=3)
INK = (40, 40, 40)  # axes, ticks and labels


def _broken(x, y, jump=180.0):
    # an angle wraps (-180 deg is 180 deg): the curve is cut where it jumps, not drawn across the plot
    cut = np.flatnonzero(np.abs(np.diff(y)) > jump) + 1
    if not cut.size:
        return x, y
    return np.insert(x, cut, (x[cut - 1] + x[cut]) / 2), np.insert(y, cut, np.nan)


# A pause between two frames this many times the usual one is an outage (a board unplugged, frames
# lost): the curves are not drawn across it.
OUTAGE = 5.0


def _outages_cut(x, y):
    # the curve is cut where time jumps by OUTAGE times the median step (a straight line across an
    # outage would show values nobody measured)
    if len(x) < 3:
        return x, y
    steps = np.diff(x)
    usual = float(np.median(steps))
    cut = np.flatnonzero(steps > OUTAGE * usual) + 1 if usual > 0 else np.zeros(0, int)
    if not cut.size:
        return x, y
    return np.insert(x, cut, (x[cut - 1] + x[cut]) / 2), np.insert(np.asarray(y, float), cut, np.nan)


class TimePlotsDock(QtWidgets.QDockWidget):
    """Plots of the whole recording over time, a cursor at the frame shown; click to seek.

    Parameters
    ----------
    model : ViewerModel
        The window's model: its source, solver and parameters are plotted,
        its frame is the cursor, and clicks set its frame.
    tasks : TaskRunner
        The window's runner: the series is solved in one of its background
        tasks (cancelled with the others when the window closes).
    parent : QWidget, optional
    error : callable, optional
        ``error(title, text)`` shows a failure to the user (an export that
        could not be written, a series that could not be solved); default a
        message box.
    notify : callable, optional
        ``notify(text)`` for passing news ("saved ..."); default none.
    live_span : float, optional
        Seconds of a live source's history drawn. Default 60.
    max_frames : int, optional
        Frames a series solves at most, evenly over the recording. Default
        :data:`tactile_viewer.model.series.MAX_FRAMES`.

    Signals
    -------
    drawn()
        The curves were redrawn (a partial series, a complete one, live frames).
    computed()
        A complete series of the recording is drawn.

    Attributes
    ----------
    series : Series or None
        What the curves show.
    plots : dict of str to pyqtgraph.PlotItem
        By row key (:data:`ROWS`, :data:`ERROR_ROWS`).
    curves, truth_curves : dict of str to pyqtgraph.PlotDataItem
        The estimate's and the truth's curve of each row of :data:`ROWS`.
    error_curves : dict of str to list of pyqtgraph.PlotDataItem
        The curves of each row of :data:`ERROR_ROWS`.
    contact_curves : dict of int to (dict of str to pyqtgraph.PlotDataItem)
        By contact identity, its curve of each row of :data:`ROWS` (only the
        contacts drawn).
    cursors : list of pyqtgraph.InfiniteLine
        One per plot.
    """

    drawn = QtCore.pyqtSignal()
    computed = QtCore.pyqtSignal()

    def __init__(self, model: ViewerModel, tasks: TaskRunner, parent=None, *, error=None, notify=None,
                 live_span: float = LIVE_SPAN_S, max_frames: int = MAX_FRAMES):
        live_span = real_number("live_span", live_span, rule="finite seconds > 0",
                                valid=lambda v: math.isfinite(v) and v > 0)
        spread_frames(0, max_frames)  # checks max_frames and names it
        super().__init__("Time plots", parent)
        self.setObjectName("time_plots")  # saveState/restoreState find the dock by it
        self.model = model
        self.tasks = tasks
        self._error = error if error is not None else self._message_box
        self._notify = notify if notify is not None else (lambda text: None)
        self.live_span = live_span
        self.max_frames = int(max_frames)
        self.series: Series | None = None
        self._generation = 0  # grows with each series asked for: results of older ones are dropped
        self._task = None
        self._partial = [None]  # the newest partial series, handed over by the solving thread
        self._drawn_partial = None
        self._stale = False  # the series shown is not of what the model shows now
        self._asked = None  # what the series being solved (or shown) is of
        self._cache: OrderedDict = OrderedDict()  # parameters -> complete series of the source and solver
        self._live: SeriesBuilder | None = None
        self._live_dirty = False
        self._cursor_x = math.nan  # the time of the frame the model shows
        self._lines_x = math.nan  # where the cursor lines stand: the frame drawn
        self._truth_shown = None
        # as the user left them last run, else the first three
        self.rows_shown = saved_rows({key for key, *_ in (*ROWS, *ERROR_ROWS)}) or set(FIRST_ROWS)
        self.lost_marks: list = []  # (plot, region) shading frames a damaged file lost

        body = QtWidgets.QWidget()
        column = QtWidgets.QVBoxLayout(body)
        column.setContentsMargins(2, 2, 2, 2)
        bar = QtWidgets.QHBoxLayout()
        self.status = QtWidgets.QLabel("no recording")
        self.csv_button = QtWidgets.QPushButton("CSV...")
        self.csv_button.setToolTip("Save the series as CSV: one row per frame, units in the header")
        self.csv_button.clicked.connect(
            lambda: self._save_dialog("Save the time series", "series.csv", "CSV (*.csv)", self.export_csv))
        self.png_button = QtWidgets.QPushButton("PNG...")
        self.png_button.setToolTip("Save the plots as a PNG image")
        self.png_button.clicked.connect(
            lambda: self._save_dialog("Save the time plots", "time_plots.png", "PNG image (*.png)",
                                      self.export_png))
        self.rows_button = QtWidgets.QToolButton()
        self.rows_button.setText("Rows")
        self.rows_button.setToolTip("Choose the plots shown (the CSV holds every series)")
        self.rows_button.setPopupMode(QtWidgets.QToolButton.ToolButtonPopupMode.InstantPopup)
        rows_menu = QtWidgets.QMenu(self.rows_button)
        self.row_actions: dict[str, QtGui.QAction] = {}
        for key, label, _unit, _ in (*ROWS, *ERROR_ROWS):
            action = rows_menu.addAction(f"{label}: {TIPS[key].split(',')[0].split(':')[0]}")
            action.setCheckable(True)
            action.setChecked(key in self.rows_shown)
            action.toggled.connect(lambda on, key=key: self.show_rows(**{key: on}))
            self.row_actions[key] = action
        self.rows_button.setMenu(rows_menu)
        bar.addWidget(self.status, 1)
        bar.addWidget(self.rows_button)
        bar.addWidget(self.csv_button)
        bar.addWidget(self.png_button)
        column.addLayout(bar)

        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.setBackground("w")
        self.graphics.setToolTip("Click a plot (or drag the cursor) to show that frame; wheel: zoom in time")
        self.plots: dict[str, pg.PlotItem] = {}
        self.curves: dict[str, pg.PlotDataItem] = {}
        self.truth_curves: dict[str, pg.PlotDataItem] = {}
        self.error_curves: dict[str, list] = {}
        self.contact_curves: dict[int, dict] = {}
        self.cursors: list[pg.InfiniteLine] = []
        first = None
        for key, label, unit, _ in ROWS:
            plot = self._plot(key, label, unit, first)
            first = first or plot
            self.curves[key] = self._curve(plot, ESTIMATE_PEN, "estimate" if key == "fz" else None)
            self.truth_curves[key] = self._curve(None, TRUTH_PEN, "truth" if key == "fz" else None)
        for key, label, unit, members in ERROR_ROWS:
            plot = self._plot(key, label, unit, first)
            self.error_curves[key] = [self._curve(plot, pen, name if len(members) > 1 else None)
                                      for pen, (name, _) in zip(ERROR_PENS, members, strict=False)]
        self._arrange(truth=False)
        self.graphics.scene().sigMouseClicked.connect(self._clicked)
        scroll = QtWidgets.QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setFrameShape(QtWidgets.QFrame.Shape.NoFrame)
        scroll.setWidget(self.graphics)
        column.addWidget(scroll, 1)
        # before anything is open: a sentence, not empty axes from 0 to 1 and a legend of nothing
        self.placeholder = QtWidgets.QLabel("The forces over time show here once a recording is open "
                                            "(File > Open) or a board connected (Live > Connect)")
        self.placeholder.setAlignment(QtCore.Qt.AlignmentFlag.AlignCenter)
        self.placeholder.setWordWrap(True)
        column.addWidget(self.placeholder, 1)
        self._plots_area = scroll
        scroll.hide()
        self.setWidget(body)
        self._set_exports()

        self._refresh_timer = QtCore.QTimer(self, interval=REFRESH_MS)
        self._refresh_timer.timeout.connect(self._refresh)
        self._settle_timer = QtCore.QTimer(self, interval=SETTLE_MS, singleShot=True)
        self._settle_timer.timeout.connect(self._start)
        self._cursor_timer = QtCore.QTimer(self, interval=CURSOR_WAIT_MS, singleShot=True)
        self._cursor_timer.timeout.connect(lambda: self._move_lines(self._cursor_x))
        self.visibilityChanged.connect(self._visibility)
        self._connections = ((model.recording_changed, self._on_source),
                             (model.parameters_changed, self._on_parameters),
                             (model.frame_changed, self._on_frame),
                             (model.solved, self._on_solved))
        for signal, slot in self._connections:
            signal.connect(slot)
        if model.is_open:
            self._on_source()

    # -- building ---------------------------------------------------------------------------

    def _plot(self, key, label, unit, first):
        plot = pg.PlotItem()
        if key in ("fz", "error"):
            # before its curves: a legend lists the named curves added after it
            plot.addLegend(offset=(-10, 5), brush=(255, 255, 255, 200), labelTextColor=INK)  # over the curves
        # small and short: it runs along a row 45 px high at 1280x800 (the tooltip spells it out)
        plot.setLabel("left", f"{label} {unit}" if unit else label, color="#282828", **{"font-size": "8pt"})
        for side in ("left", "bottom"):
            plot.getAxis(side).setPen(INK)
            plot.getAxis(side).setTextPen(INK)
        axis = plot.getAxis("left")
        axis.enableAutoSIPrefix(False)  # the unit is in the label: mN stays mN
        axis.setWidth(60)  # one width for all: the stacked time axes line up
        axis.setToolTip(TIPS[key])
        if key == "direction":
            # an angle has its own fixed range: every direction in view, the quarters marked
            axis.setTicks(ANGLE_TICKS)
            plot.setYRange(-180, 180, padding=0.05)
        plot.setLabel("bottom", "t (s)", color="#282828")
        # no grid: pyqtgraph draws it with the axis, which then repaints over the whole plot each time
        # the cursor moves (measured under Xvfb: the dock's repaint per frame 13 ms with it, 2 ms without)
        plot.setMouseEnabled(x=True, y=False)  # wheel and drag move through time; each y follows its data
        if key != "direction":
            plot.setAutoVisible(y=True)
        plot.setMenuEnabled(False)
        if first is not None:
            plot.setXLink(first)
        cursor = pg.InfiniteLine(angle=90, movable=True, pen=CURSOR_PEN, hoverPen=CURSOR_HOVER_PEN)
        cursor.setToolTip("The frame drawn: drag to move through the recording")
        cursor.sigDragged.connect(self._dragged)
        cursor.sigPositionChangeFinished.connect(lambda _: self._move_lines(self._lines_x))
        cursor.setVisible(False)
        plot.addItem(cursor, ignoreBounds=True)  # the cursor never widens the plotted range
        self.cursors.append(cursor)
        self.plots[key] = plot
        return plot

    @staticmethod
    def _curve(plot, pen, name):
        curve = pg.PlotDataItem(pen=pen, name=name, connect="finite")
        # a long take draws only what is in view, thinned to the pixels it covers
        curve.setClipToView(True)
        curve.setDownsampling(auto=True, method="peak")
        if plot is not None:
            plot.addItem(curve)
        return curve

    def show_rows(self, **shown: bool):
        """Show (True) or hide (False) rows by key (:data:`ROWS`, :data:`ERROR_ROWS`); one stays."""
        unknown = set(shown) - set(self.plots)
        if unknown:
            raise ValueError(f"rows must be among {sorted(self.plots)}, got {sorted(unknown)}")
        rows = {key for key in self.rows_shown if shown.get(key, True)} | {k for k, on in shown.items() if on}
        if not rows & {key for key, *_ in ROWS}:
            rows.add("fz")  # a plot with no row has no time axis to stand on
        self.rows_shown = rows
        save_rows(rows)
        for key, action in self.row_actions.items():
            action.blockSignals(True)
            action.setChecked(key in rows)
            action.blockSignals(False)
        self._arrange(bool(self._truth_shown), again=True)

    def _arrange(self, truth: bool, again: bool = False):
        # the truth curves and the error rows are there when the series has a truth, only then
        if truth == self._truth_shown and not again:
            return
        self._truth_shown = truth
        layout = self.graphics.ci
        for key, curve in self.truth_curves.items():
            plot = self.plots[key]
            if truth and curve not in plot.items:
                plot.addItem(curve)  # the legend takes it by its name
            elif not truth and curve in plot.items:
                plot.removeItem(curve)  # and gives it back here
        keys = [key for key, *_ in ROWS if key in self.rows_shown] + (
            [key for key, *_ in ERROR_ROWS if key in self.rows_shown] if truth else [])
        for plot in self.plots.values():
            if plot in layout.items:
                layout.removeItem(plot)
        for row, key in enumerate(keys):
            layout.addItem(self.plots[key], row=row, col=0)
        for key, plot in self.plots.items():
            # one time axis, under the lowest plot: the others share it
            plot.showAxis("bottom", key == keys[-1])
        self.graphics.setMinimumHeight(ROW_PX * len(keys) + AXIS_PX)

    # -- following the model -----------------------------------------------------------------

    def detach(self):
        """Stop following the model and cancel the series being solved (the dock is being removed)."""
        for signal, slot in self._connections:
            try:
                signal.disconnect(slot)
            except ValueError:
                pass  # detached before
        self._cancel()
        self._settle_timer.stop()
        self._refresh_timer.stop()
        self._cursor_timer.stop()

    def _on_source(self):
        # a new source, or the same one with another solver (kernel, quality): all of it again
        self._cache.clear()
        self._cancel()
        model = self.model
        self._live = None
        self.placeholder.hide()
        self._plots_area.show()
        self._mark_lost(() if model.live or model.recording is None else model.recording.lost_spans)
        if model.live:
            self._live = SeriesBuilder(model.grid, kernel=model.kernel, mode="as shown",
                                       source=model.source.label, span=self.live_span)
            self._asked = None
            self._draw(self._live.series())
            self.status.setText(f"live: the last {self.live_span:g} s of frames solved")
            self._refresh_timer.start()
            return
        if model.recording is not None:
            self._cursor_x = float(model.recording.t[model.frame])
            self._cursor_timer.start()
        if self.series is not None and (self._asked is None or self._asked[0] is not model.recording):
            # another recording: its curves replace these as they are solved, none of these stay meanwhile
            self._draw(SeriesBuilder(model.grid).series())
        self._start()

    def _mark_lost(self, spans):
        # frames a damaged file lost: shaded on every row, so that a gap in the curves is not read
        # as a quiet skin
        for plot, mark in self.lost_marks:
            plot.removeItem(mark)
        self.lost_marks = []
        for start, stop in spans:
            for plot in self.plots.values():
                mark = pg.LinearRegionItem(values=(start, stop), movable=False, brush=LOST_BRUSH,
                                           pen=pg.mkPen(None))
                mark.setToolTip(f"frames lost to damage in the file, t {start:.3f} to {stop:.3f} s")
                plot.addItem(mark, ignoreBounds=True)
                self.lost_marks.append((plot, mark))

    def _on_parameters(self):
        if self.model.live or not self.model.is_open:
            return
        # stop solving the old parameters at once (the window's own solves need the processor during a
        # drag); solve the new ones when they have settled
        self._cancel()
        self.status.setText("parameters changed: the series follows when they settle...")
        self._settle_timer.start()

    def _on_frame(self, index: int):
        # The cursor is at this frame now; its lines move when the frame's result is drawn (solved), in
        # the window's repaint of that frame. Moved here, they cost the window a repaint of its own on
        # every frame (measured under Xvfb: the frame slider's latency 100 ms instead of 63). A result
        # that does not come (a failed or very slow solve): they move after CURSOR_WAIT_MS anyway.
        recording = self.model.recording
        if recording is not None:
            self._cursor_x = float(recording.t[index])
            self._cursor_timer.start()

    def _on_solved(self, solved):
        if self._live is not None:
            if self.model.live:
                self._live.add(solved)
                self._live_dirty = True
            self._cursor_x = solved.time
            self._move_lines(solved.time)
            return
        if solved.frame == self.model.frame:
            self._cursor_timer.stop()  # the frame shown is drawn: the lines come with it
        self._move_lines(solved.time)
        asked = self._asked
        if asked is not None and self.model.recording is not asked[0]:
            # the recording was re-tared: same file, other stresses
            self._cache.clear()
            self._start()

    def _visibility(self, visible: bool):
        if visible:
            self._move_lines(self._lines_x)
            if self._stale:
                self._start()

    # -- the series --------------------------------------------------------------------------------

    def _wanted(self):
        # what the series must be of now: the recording, its solver, the parameters
        model = self.model
        parameters = None if model.auto else (model.shear_ratio, model.shear_direction)
        return model.recording, model.reconstructor, parameters

    def _start(self):
        self._settle_timer.stop()
        self._cancel()
        model = self.model
        if model.recording is None or model.reconstructor is None:
            return
        wanted = self._wanted()
        recording, solver, parameters = wanted
        self._asked = wanted
        if not self.isVisible():
            self._stale = True  # solved when the dock is shown: a hidden dock costs nothing
            return
        self._stale = False
        if parameters in self._cache:
            self._cache.move_to_end(parameters)
            self._finish(self._cache[parameters])
            return
        self._generation += 1
        generation = self._generation
        frames = spread_frames(len(recording), self.max_frames)
        given = {} if parameters is None else dict(shear_ratio=parameters[0], shear_direction=parameters[1])
        box = self._partial = [None]
        source = str(model.path) if model.path is not None else recording.description

        def work(progress):
            # on the task's thread: only reads the recording and the solver (series.py says why it may)
            return compute_series(recording, solver, frames=frames, progress=progress, every=REFRESH_MS / 1e3,
                                  partial=lambda series: box.__setitem__(0, series), source=source, **given)

        self.status.setText(f"solving {len(frames)} frames...")
        self._task = self.tasks.background(work, lambda series: self._done(generation, series),
                                           lambda exc: self._failed(generation, exc))
        if self._task.isRunning():
            # a background job: where the platform lets threads have priorities, the window's come first
            self._task.setPriority(QtCore.QThread.Priority.LowPriority)
        self._set_exports()
        self._refresh_timer.start()

    def _cancel(self):
        # the running series is dropped; its thread stops after the frame it is solving
        self._generation += 1
        if self._task is not None:
            self._task.cancel()
            self._task = None
        self._partial = [None]
        self._set_exports()

    def _done(self, generation: int, series: Series):
        if generation != self._generation:
            return
        self._task = None
        parameters = self._asked[2]
        self._cache[parameters] = series
        while len(self._cache) > CACHED:
            self._cache.popitem(last=False)
        self._finish(series)

    def _finish(self, series: Series):
        self._draw(series)
        mode = "Auto" if series.mode == "auto" else (
            f"shear ratio {series.shear_ratio:.2f}, direction {math.degrees(series.shear_direction):.0f} deg")
        sampled = "" if len(series) == len(self.model.recording) else f" (of {len(self.model.recording)})"
        refused = (f"; {len(series.refused)} refused by the solver (values beyond {MAX_STRESS:g} Pa), "
                   f"first frame {series.refused[0]}" if series.refused else "")
        self.status.setText(f"{len(series)} frames{sampled}, {series.kernel} kernel, {mode}{refused}")
        self._set_exports()
        self.computed.emit()

    def _failed(self, generation: int, exc: BaseException):
        if generation != self._generation or isinstance(exc, Cancelled):
            return
        self._task = None
        self._set_exports()
        self.status.setText("the series could not be solved")
        self._error("Time plots", f"solving the series failed: {exc}")

    def _refresh(self):
        # the timer: a partial series, or the live frames that came since the last look
        if self._live is not None:
            if self._live_dirty:
                self._live_dirty = False
                self._draw(self._live.series())
            return
        partial = self._partial[0]
        if self._task is None:
            self._refresh_timer.stop()
        elif partial is not None and partial is not self._drawn_partial:
            self._drawn_partial = partial
            self._draw(partial)
            self.status.setText(f"solving: {len(partial)} of {partial.total} frames...")

    # -- drawing ---------------------------------------------------------------------------------

    def _draw(self, series: Series):
        self.series = series
        truth = series.truth is not None
        self._arrange(truth)
        x = series.t
        for key, _, _, value in ROWS:
            wrap = key == "direction"
            self._set(self.curves[key], x, value(series.estimate), wrap)
            if truth:
                self._set(self.truth_curves[key], x, value(series.truth), wrap)
        if truth:
            for key, *_, members in ERROR_ROWS:
                for curve, (_, value) in zip(self.error_curves[key], members, strict=True):
                    curve.setData(x, value(series.errors))
        self._draw_contacts(series)
        self._move_lines(self._lines_x)
        self._set_exports()
        self.drawn.emit()

    def _draw_contacts(self, series: Series):
        # a curve per followed contact on every row, when there is more than one
        contacts = series.contacts if len(series.contacts) > 1 else ()
        if len(contacts) > MAX_CONTACT_CURVES:
            present = sorted(contacts, key=lambda pair: -np.count_nonzero(np.isfinite(pair[1].fz)))
            contacts = sorted(present[:MAX_CONTACT_CURVES], key=lambda pair: pair[0])
        drawn = {identity for identity, _ in contacts}
        for identity in [i for i in self.contact_curves if i not in drawn]:
            for key, curve in self.contact_curves.pop(identity).items():
                self.plots[key].removeItem(curve)  # and from the legend
        for identity, quantities in contacts:
            curves = self.contact_curves.get(identity)
            if curves is None:
                pen = pg.mkPen(CONTACT_COLOURS[(identity - 1) % len(CONTACT_COLOURS)], width=1.5)
                curves = self.contact_curves[identity] = {
                    key: self._curve(self.plots[key], pen, f"#{identity}" if key == "fz" else None)
                    for key, *_ in ROWS}
            for key, _, _, value in ROWS:
                self._set(curves[key], series.t, value(quantities), key == "direction")

    @staticmethod
    def _set(curve, x, y, wrap):
        if wrap:
            x, y = _broken(x, y)
        curve.setData(*_outages_cut(x, y))

    def _move_lines(self, x: float):
        # the one thing that moves during playback: a few line items, never the curves
        self._lines_x = x
        if not self.isVisible():
            return
        shown = math.isfinite(x)
        for cursor in self.cursors:
            if cursor.moving:
                continue  # the user holds it: the others follow it, it follows the mouse
            cursor.setVisible(shown)
            if shown:
                cursor.setValue(x)

    @property
    def cursor_time(self) -> float:
        """Seconds of the frame the model shows: where the cursor goes (nan: no frame yet).

        Its lines get there with the frame's result (:attr:`lines_time`).
        """
        return self._cursor_x

    @property
    def lines_time(self) -> float:
        """Seconds at which the cursor's lines stand: the frame drawn (nan: none yet)."""
        return self._lines_x

    # -- seeking ------------------------------------------------------------------------------

    def seek_time(self, x: float) -> bool:
        """Show the recording's frame nearest to ``x`` seconds; False for a live source or nothing."""
        recording = self.model.recording
        if recording is None or self.model.live or not math.isfinite(x):
            return False
        self.model.set_frame(nearest_frame(recording.t, x))
        return True

    def _clicked(self, event):
        if event.button() != QtCore.Qt.MouseButton.LeftButton:
            return
        if event.double():
            # undo any zoom, as a double-click does in most plotting tools (pyqtgraph's own is a small
            # corner button)
            for plot in self.plots.values():
                plot.enableAutoRange()
            return
        position = event.scenePos()
        for plot in self.plots.values():
            box = plot.getViewBox()
            if plot.scene() is not None and box.sceneBoundingRect().contains(position):
                self.seek_time(box.mapSceneToView(position).x())
                return

    def _dragged(self, cursor):
        x = cursor.value()
        for other in self.cursors:
            if other is not cursor:
                other.setValue(x)
        self.seek_time(x)

    # -- exports -------------------------------------------------------------------------------

    def _set_exports(self):
        # a complete series only: a partial one is not what the plots will show
        series = self.series
        ready = self._task is None and series is not None and len(series) > 0 and series.complete
        self.csv_button.setEnabled(ready)
        self.png_button.setEnabled(ready)

    def export_csv(self, path) -> Path | None:
        """Write the series drawn as CSV (:meth:`Series.to_csv`); None (the error shown) when it cannot."""
        series = self.series
        if series is None or not len(series):
            self._error("Nothing to export", "no series has been solved yet")
            return None
        if self._task is not None or not series.complete:
            self._error("Series not complete", f"the series is still being solved ({len(series)} of "
                        f"{series.total} frames): export it when it is complete")
            return None
        try:
            written = series.to_csv(path)
        except OSError as exc:
            self._error("Cannot save the series", f"{path}: {exc.strerror or exc}")
            return None
        self._notify(f"saved {written}")
        return written

    def export_png(self, path) -> Path | None:
        """Write the plots as a PNG image; None (and the error shown) when it cannot."""
        path = Path(path)
        image = self.graphics.grab()
        try:
            with written_whole(path) as temporary:
                if image.isNull() or not image.save(str(temporary), "PNG"):
                    raise OSError("the image could not be written")
        except OSError:
            self._error("Cannot save the plots", f"{path}: the image could not be written (check the folder "
                        "exists and may be written to)")
            return None
        self._notify(f"saved {path}")
        return path

    def _save_dialog(self, title: str, default: str, file_filter: str, export):
        # the name picked, given the default's ending (a name so made must be free), to ``export``
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self, title, default, file_filter)
        if path:
            try:
                export(derived_name(path, Path(default).suffix, what=Path(default).stem.replace("_", " ")))
            except FileExistsError as exc:
                self._error(f"Cannot {title[0].lower()}{title[1:]}", str(exc.strerror))

    def _message_box(self, title, text):
        QtWidgets.QMessageBox.critical(self, title, text)
