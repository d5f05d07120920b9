"""The taxel read-out: what the taxel under the mouse carries, as one line of text.

An event filter on the scene's widget follows the mouse without taking any
event from it (rotating, panning and zooming work as before): on a move it
looks up, at most once per ``interval`` milliseconds, the taxel under the
cursor (:meth:`~tactile_viewer.render.scene.Scene.node_at`, camera arithmetic,
nothing rendered) and emits its line (:func:`~tactile_viewer.render.taxel_readout.taxel_text`),
or ``""`` off the skin. A click (press and release without dragging) pins
the taxel under it: the line then stays on that taxel, and follows its
values frame by frame, until a click pins another or one off the skin (or
on the pinned taxel) lets it go.
"""

from __future__ import annotations

import logging

from PyQt6 import QtCore

from ..model.viewer_model import ViewerModel
from ..render.scene import Scene
from ..render.taxel_readout import taxel_text

log = logging.getLogger(__name__)

__all__ = ["TaxelReadout"]

CLICK_PX = 4  # a press and release farther apart than this is a drag (the camera turned), not a click


class TaxelReadout(QtCore.QObject):
    """Reads out the taxel under the mouse over the scene's widget.

    Parameters
    ----------
    widget : QtWidgets.QWidget
        The scene's widget (``QtInteractor.interactor``).
    scene : Scene
        The scene drawn in it.
    model : ViewerModel
        The values read out are those of ``model.last``.
    interval : int, optional
        Milliseconds between lookups while the mouse moves. Default 40.

    Signals
    -------
    text_changed(str)
        The read-out changed: a taxel's line (ending in ``"(pinned)"`` when
        pinned), or ``""`` when the mouse left the skin and nothing is pinned.
    """

    text_changed = QtCore.pyqtSignal(str)

    def __init__(self, widget, scene: Scene, model: ViewerModel, *, interval: int = 40, parent=None):
        super().__init__(parent if parent is not None else widget)
        self.widget, self.scene, self.model = widget, scene, model
        self.node: int | None = None  # the taxel read out
        self.pinned = False
        self.text = ""
        self._position = None  # the newest mouse position not looked up yet (widget coordinates)
        self._pressed = None
        self._failed = False
        self._timer = QtCore.QTimer(self, singleShot=True, interval=int(interval))
        self._timer.timeout.connect(self._look)
        widget.setMouseTracking(True)  # moves without a button pressed
        widget.installEventFilter(self)
        model.solved.connect(self._solved)
        model.recording_changed.connect(self._new_source)

    # -- events ----------------------------------------------------------------------------

    def eventFilter(self, watched, event):  # noqa: N802 (Qt's name)
        try:
            kind = event.type()
            types = QtCore.QEvent.Type
            if kind == types.MouseMove:
                self._position = event.position()
                if not self._timer.isActive():
                    self._timer.start()  # the newest position is looked up when it fires
            elif kind == types.Leave:
                self._position = None
                self._timer.stop()
                if not self.pinned:
                    self._show(None)
            elif kind == types.MouseButtonPress and event.button() == QtCore.Qt.MouseButton.LeftButton:
                self._pressed = event.position()
            elif kind == types.MouseButtonRelease and event.button() == QtCore.Qt.MouseButton.LeftButton:
                pressed, self._pressed = self._pressed, None
                if pressed is not None and (event.position() - pressed).manhattanLength() <= CLICK_PX:
                    self._click(event.position())
        except Exception:  # a read-out must never cost the user the window: say so once, in the log
            self._fail()
        return False  # every event goes on to the scene (turning, panning, zooming)

    def _look(self):
        position, self._position = self._position, None
        if position is None or self.pinned:
            return
        try:
            self._show(self.node_at(position))
        except Exception:
            self._fail()

    def _click(self, position):
        node = self.node_at(position)
        if node is None or (self.pinned and node == self.node):
            self.pinned = False  # let go; the mouse's next move reads out what is under it
            self._show(node)
        else:
            self.pinned = True
            self._show(node)

    def _solved(self, solved):
        # a new frame: the same taxel's new values
        try:
            if self.node is not None:
                self._show(self.node)
        except Exception:
            self._fail()

    def _new_source(self):
        self.pinned = False
        self._show(None)

    # -- helpers --------------------------------------------------------------------------------

    def node_at(self, position) -> int | None:
        """The node under a point of the widget (``QPointF``, logical pixels from its top left)."""
        ratio = self.widget.devicePixelRatioF()
        # VTK's display: device pixels, y up from the bottom row (as pyvistaqt passes mouse events)
        return self.scene.node_at(position.x() * ratio, (self.widget.height() - position.y() - 1) * ratio)

    def _show(self, node):
        grid = self.scene.grid
        if node is not None and (grid is None or node >= grid.size):
            node = None
        self.node = node
        if node is None:
            self.pinned = False
            text = ""
        else:
            text = taxel_text(self.model.last, grid, node) + ("  (pinned)" if self.pinned else "")
        if text != self.text:
            self.text = text
            self.text_changed.emit(text)

    def _fail(self):
        if not self._failed:
            self._failed = True
            log.exception("taxel read-out failed (later failures are not logged)")
        self.node, self.pinned = None, False
