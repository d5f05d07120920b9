"""A line of text that changes every frame (tactile_viewer/qt/text_line.py)."""

import pytest
from PyQt6 import QtCore, QtGui, QtWidgets

from tactile_viewer.qt.text_line import TextLine


class LayoutRequests(QtCore.QObject):
    """Counts the layout requests a widget receives."""

    def __init__(self, watched):
        super().__init__()
        self.count = 0
        watched.installEventFilter(self)

    def eventFilter(self, watched, event):  # noqa: N802
        if event.type() == QtCore.QEvent.Type.LayoutRequest:
            self.count += 1
        return False


def status_bar_with(qtbot, line):
    window = QtWidgets.QMainWindow()
    qtbot.addWidget(window)
    window.statusBar().addWidget(line, 1)
    window.statusBar().addPermanentWidget(QtWidgets.QLabel("taxel 117"))
    window.resize(640, 200)
    window.show()
    qtbot.waitExposed(window)
    QtWidgets.QApplication.processEvents()
    return window


TEXTS = ["frame 1 (of 0-59)  t 0.033 s  |  2.41 ms", "frame 12 (of 0-59)  t 0.400 s  |  12.07 ms  |  auto: #1 mu 0.31",
         "frame 2", ""]


@pytest.mark.parametrize("kind", [TextLine, QtWidgets.QLabel])
def test_a_new_text_asks_no_new_layout_of_the_window(qtbot, kind):
    # the QLabel is the case the class exists for: each new text asks the status bar for a layout,
    # which repaints it whole (a second composition of the window when it comes after the frame's)
    line = kind("ready")
    window = status_bar_with(qtbot, line)
    requests = LayoutRequests(window.statusBar())
    for text in TEXTS:
        line.setText(text)
        QtWidgets.QApplication.processEvents()
        assert line.text() == text
    if kind is TextLine:
        assert requests.count == 0
    else:
        assert requests.count >= 2  # what the test would see of a QLabel: it can fail


def test_the_line_keeps_the_room_asked_for_and_draws_a_long_text_inside_itself(qtbot):
    line = TextLine("-", room_for="frame 0000 (of 0-0000),  t = 000.000 s")
    qtbot.addWidget(line)
    metrics = line.fontMetrics()
    assert line.sizeHint().width() >= metrics.horizontalAdvance("frame 0000 (of 0-0000),  t = 000.000 s")
    assert line.sizeHint().height() >= metrics.height()
    assert line.sizePolicy().verticalPolicy() == QtWidgets.QSizePolicy.Policy.Fixed
    # without room asked for, the layout decides its width (the status line's stretch)
    assert TextLine().sizePolicy().horizontalPolicy() == QtWidgets.QSizePolicy.Policy.Ignored
    # drawn: a text longer than the line stays inside it (cut with an ellipsis), never past its edge
    line.resize(120, line.sizeHint().height())
    line.setText("W" * 200)
    image = QtGui.QImage(line.size(), QtGui.QImage.Format.Format_ARGB32)
    image.fill(QtGui.QColor("white"))
    line.render(image)
    ink = [x for x in range(image.width()) for y in range(image.height())
           if QtGui.QColor(image.pixel(x, y)).lightness() < 128]
    assert ink and max(ink) < 120 - 2  # the right margin stays clear
    assert line.text() == "W" * 200  # the whole text is kept (tooltips and tests read it)


def test_a_new_font_asks_for_a_new_height(qtbot):
    line = TextLine("x")
    window = status_bar_with(qtbot, line)
    before = line.sizeHint().height()
    font = line.font()
    font.setPointSizeF(font.pointSizeF() * 2)
    line.setFont(font)
    QtWidgets.QApplication.processEvents()
    assert line.sizeHint().height() > before
    assert line.height() > before  # the status bar made room
    assert window.statusBar().isVisible()
