"""The stacked time plots: one pyqtgraph plot per row of a series over one time axis, a cursor on each.

The widget of :class:`tactile_viewer.qt.time_plots.TimePlotsDock`: the plots of
the rows shown (:mod:`tactile_viewer.model.time_plot_rows`), the estimate's
curves, the truth's and the errors' when the series has a truth, a thin curve
per followed contact, the shading of frames a damaged file lost, and the
cursor lines; a click on a plot (or dragging a cursor) asks for the frame at
that time (:attr:`TimePlotStack.seek_requested`), a double click undoes a
zoom. It draws what it is given; the dock decides what and when.
"""

from __future__ import annotations

import math

import pyqtgraph as pg  # takes the Qt binding already imported (the window's PyQt6), else PyQt6 first
from PyQt6 import QtCore

from ..model.series import Series
from ..model.time_plot_rows import ANGLE_TICKS, ERROR_ROWS, ROWS, TIPS, contacts_drawn, curve_data

__all__ = ["TimePlotStack"]

ROW_PX = 45  # the least height of one plot: below it the dock scrolls instead of squashing them
AXIS_PX = 35  # the time axis under the lowest plot shown
LEGEND_PX = 15  # the line above a plot that names its curves (the Fz and error rows)
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


class _ShortSample(pg.ItemSample):
    # pyqtgraph's legend sample, 14 px high instead of 20: the legend's line fits its row
    def __init__(self, item):
        super().__init__(item)
        self.setFixedHeight(14)

    def boundingRect(self):
        return QtCore.QRectF(0, 0, 20, 14)

    def paint(self, painter, *args):
        painter.translate(0, -4)  # its line at 7 px, the label's middle
        super().paint(painter, *args)


class _OneLineLegend(pg.LegendItem):
    # the legend of a plot on one line in the plot's title row, above its curves: samples 14 px high,
    # labels without their text's 4 px margins (the line was 21 px high)
    def addItem(self, item, name):
        super().addItem(item, name)
        label = self.items[-1][1]
        label.item.document().setDocumentMargin(0)
        label.updateMin()
        label.setMaximumHeight(label.minimumHeight())
        self.updateSize()

    def updateSize(self):
        # as wide and high as its entries: pyqtgraph's reads their laid-out sizes, stale until the next
        # layout pass
        self.resize(self.layout.effectiveSizeHint(QtCore.Qt.SizeHint.PreferredSize))


class TimePlotStack(pg.GraphicsLayoutWidget):
    """The plots of a series stacked over one time axis, a cursor line on each; click to seek.

    Parameters
    ----------
    rows_shown : set of str
        The row keys shown at first (:data:`~tactile_viewer.model.time_plot_rows.ROWS`,
        :data:`~tactile_viewer.model.time_plot_rows.ERROR_ROWS`).
    parent : QWidget, optional

    Signals
    -------
    seek_requested(float)
        A click on a plot, or a cursor dragged, asks for the frame nearest
        to these seconds.

    Attributes
    ----------
    rows_shown : set of str
        The row keys shown (error rows only beside a truth).
    plots : dict of str to pyqtgraph.PlotItem
        By row key.
    curves, truth_curves : dict of str to pyqtgraph.PlotDataItem
        The estimate's and the truth's curve of each row of ``ROWS``.
    error_curves : dict of str to list of pyqtgraph.PlotDataItem
        The curves of each row of ``ERROR_ROWS``.
    contact_curves : dict of int to (dict of str to pyqtgraph.PlotDataItem)
        By contact identity, its curve of each row of ``ROWS`` (only the
        contacts drawn).
    cursors : list of pyqtgraph.InfiniteLine
        One per plot.
    lost_marks : list of (pyqtgraph.PlotItem, pyqtgraph.LinearRegionItem)
        The shading of frames a damaged file lost.
    """

    seek_requested = QtCore.pyqtSignal(float)

    def __init__(self, rows_shown, parent=None):
        super().__init__(parent)
        self.setBackground("w")
        self.setToolTip("Click a plot (or drag the cursor) to show that frame; wheel: zoom in time")
        self.rows_shown = set(rows_shown)
        self._truth_shown = None
        self._cursors_x = math.nan  # where the cursor lines were put last
        self.lost_marks: list = []  # (plot, region) shading frames a damaged file lost
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
        self.arrange(truth=False)
        self.scene().sigMouseClicked.connect(self._clicked)

    # -- building ---------------------------------------------------------------------------

    def _plot(self, key, label, unit, first):
        plot = pg.PlotItem()
        if key in ("fz", "error"):
            # before its curves: a legend lists the named curves added after it (PlotItem.addItem). On
            # one line in the plot's title row, above its curves: inside the view it covered the curves
            # it names; the row is LEGEND_PX more than the others, so its curves keep as much height
            plot.layout.setRowFixedHeight(0, LEGEND_PX)
            legend = _OneLineLegend(offset=None, colCount=len(CONTACT_COLOURS) + 2, labelTextColor=INK,
                                    labelTextSize="8pt", horSpacing=4, verSpacing=0, sampleType=_ShortSample)
            legend.layout.setContentsMargins(0, 0, 0, 0)
            legend.setParentItem(plot)
            legend.anchor(itemPos=(1, 0), parentPos=(1, 0), offset=(-5, 0))
            plot.legend = legend
        # small and short: it runs along a row 45 px high at 1280x800 (the tooltip spells it out)
        plot.setLabel("left", f"{label} {unit}" if unit else label, color="#282828", **{"font-size": "7.5pt"})
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
        cursor.sigPositionChangeFinished.connect(lambda _: self.move_cursors(self._cursors_x))
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

    def show_rows(self, rows) -> None:
        """Show the rows of these keys (error rows only beside a truth)."""
        self.rows_shown = set(rows)
        self.arrange(bool(self._truth_shown), again=True)

    def arrange(self, truth: bool, again: bool = False):
        """Lay out the rows shown, with the truth's curves and error rows when ``truth``."""
        # the truth curves and the error rows are there when the series has a truth, only then
        if truth == self._truth_shown and not again:
            return
        self._truth_shown = truth
        layout = self.ci
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
            # each plot's curves as high as the others': its legend's row and the time axis on top
            plot.setPreferredHeight(ROW_PX + (LEGEND_PX if plot.legend is not None else 0)
                                    + (AXIS_PX if key == keys[-1] else 0))
        legends = sum(self.plots[key].legend is not None for key in keys)
        self.setMinimumHeight(ROW_PX * len(keys) + AXIS_PX + LEGEND_PX * legends)

    def mark_lost(self, spans):
        """Shade the ``(start, stop)`` seconds of frames a damaged file lost on every row (none: clear)."""
        # frames a damaged file lost: shaded on every row, so that a gap in the curves is not read
        # as a quiet skin
        for plot, mark in self.lost_marks:
            plot.removeItem(mark)
        self.lost_marks.clear()
        for start, stop in spans:
            for plot in self.plots.values():
                mark = pg.LinearRegionItem(values=(start, stop), movable=False, brush=LOST_BRUSH,
                                           pen=pg.mkPen(None))
                mark.setToolTip(f"frames lost to damage in the file, t {start:.3f} to {stop:.3f} s")
                plot.addItem(mark, ignoreBounds=True)
                self.lost_marks.append((plot, mark))

    # -- drawing ---------------------------------------------------------------------------------

    def draw(self, series: Series) -> None:
        """Draw ``series``: its estimate, its truth and errors when it has them, its contacts."""
        truth = series.truth is not None
        self.arrange(truth)
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

    def _draw_contacts(self, series: Series):
        # a curve per followed contact on every row, when there is more than one
        contacts = contacts_drawn(series)
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
        curve.setData(*curve_data(x, y, wrap))

    def move_cursors(self, x: float) -> None:
        """Put the cursor lines at ``x`` seconds (nan: hide them); one the user holds follows the mouse."""
        # the one thing that moves during playback: a few line items, never the curves
        self._cursors_x = x
        shown = math.isfinite(x)
        for cursor in self.cursors:
            if cursor.moving:
                continue  # the user holds it: the others follow it, it follows the mouse
            cursor.setVisible(shown)
            if shown:
                cursor.setValue(x)

    # -- seeking ------------------------------------------------------------------------------

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
                self.seek_requested.emit(box.mapSceneToView(position).x())
                return

    def _dragged(self, cursor):
        x = cursor.value()
        for other in self.cursors:
            if other is not cursor:
                other.setValue(x)
        self.seek_requested.emit(x)
