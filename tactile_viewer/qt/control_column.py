"""The controls column's scroll area: up and down on a short screen, never sideways.

On a 1280x800 screen the panels fit unscrolled; a shorter window (a taller
font, a preset's note) scrolls them rather than push the status bar off the
screen. The column is never narrower than its widest control, and widens by its
scroll bar while that shows, so the bar covers none of it.
"""

from __future__ import annotations

from PyQt6 import QtCore, QtWidgets

__all__ = ["ControlColumn"]


class ControlColumn(QtWidgets.QScrollArea):
    """``controls`` in a scroll area as wide as their widest control, plus the scroll bar when it shows.

    In a :class:`~PyQt6.QtWidgets.QDockWidget` of a main window, a column that
    widened only for its scroll bar narrows back when the bar goes, so a window
    made taller again is laid out as before.
    """

    def __init__(self, controls: QtWidgets.QWidget, parent=None):
        super().__init__(parent)
        self.setWidget(controls)
        self.setWidgetResizable(True)
        self.setFrameShape(QtWidgets.QFrame.Shape.NoFrame)
        self.setHorizontalScrollBarPolicy(QtCore.Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        controls.setMinimumWidth(controls.sizeHint().width())
        self.setMinimumWidth(controls.minimumWidth())
        self.verticalScrollBar().rangeChanged.connect(self._fit)

    def _fit(self, *_):
        bar = self.verticalScrollBar()
        width = self.widget().minimumWidth() + (bar.sizeHint().width() if bar.maximum() > 0 else 0)
        before = self.minimumWidth()
        if width == before:
            return
        self.setMinimumWidth(width)  # wider: the window's layout widens the dock to it
        dock, window = self.parentWidget(), self.window()
        if (width < before and self.width() == before and isinstance(dock, QtWidgets.QDockWidget)
                and isinstance(window, QtWidgets.QMainWindow)):
            # it was as narrow as it could be: back to the width it had before the bar came
            window.resizeDocks([dock], [dock.width() - (before - width)], QtCore.Qt.Orientation.Horizontal)
