"""One line of text that changes every frame and costs only its own repaint.

A ``QLabel`` asks for a new layout of its window at every new text (its size
hint may have changed), even where no layout could use it: the status bar then
repaints whole, and where that comes after the frame's paint, the window is
composed a second time. With the 3-D view a ``QOpenGLWidget``, Qt composes the
whole window through OpenGL on every paint, and under software rendering that
second composition took 10 to 15 ms on about half the frames of a playing
recording (measured in ``docs/efficiency.md``). :class:`TextLine` keeps the size
it was given: a new text repaints the line and nothing else.
"""

from __future__ import annotations

from PyQt6 import QtCore, QtGui, QtWidgets

__all__ = ["TextLine"]

_MARGIN = 4  # px on the right: the next widget's text never touches this one's


class TextLine(QtWidgets.QWidget):
    """A single line of text, cut with an ellipsis where it does not fit.

    Parameters
    ----------
    text : str, optional
        Shown first.
    room_for : str, optional
        The widest text expected: the width asked of the layout (at least);
        empty (the default) asks for none, the line takes what its layout
        gives it.
    parent : QWidget, optional
    """

    def __init__(self, text: str = "", *, room_for: str = "", parent=None):
        super().__init__(parent)
        self._text = text
        self._room_for = room_for
        policy = QtWidgets.QSizePolicy.Policy
        self.setSizePolicy(policy.Ignored if not room_for else policy.Preferred, policy.Fixed)

    def text(self) -> str:
        """The whole text (the tooltip or a test reads it; the screen may show it cut)."""
        return self._text

    def setText(self, text: str) -> None:  # noqa: N802 (Qt's name, as QLabel's)
        """Show ``text``: a repaint of this line only."""
        if text != self._text:
            self._text = text
            self.update()

    def sizeHint(self) -> QtCore.QSize:  # noqa: N802
        metrics = self.fontMetrics()
        return QtCore.QSize(metrics.horizontalAdvance(self._room_for) + _MARGIN, metrics.height() + 2)

    def minimumSizeHint(self) -> QtCore.QSize:  # noqa: N802
        return QtCore.QSize(0, self.sizeHint().height())

    def changeEvent(self, event):  # noqa: N802
        if event.type() == QtCore.QEvent.Type.FontChange:
            self.updateGeometry()  # the one change that does move the layout
        super().changeEvent(event)

    def paintEvent(self, event):  # noqa: N802
        painter = QtGui.QPainter(self)
        width = max(self.width() - _MARGIN, 0)
        shown = self.fontMetrics().elidedText(self._text, QtCore.Qt.TextElideMode.ElideRight, width)
        painter.drawText(QtCore.QRect(0, 0, width, self.height()),
                         int(QtCore.Qt.AlignmentFlag.AlignLeft | QtCore.Qt.AlignmentFlag.AlignVCenter), shown)
        painter.end()
