"""Publishing the window's live forces over Lab Streaming Layer (Live > Publish over LSL). No Qt.

:class:`ForcePublishing` follows a :class:`~tactile_viewer.model.viewer_model.ViewerModel`:
while on, every live frame it solves goes out through a
:class:`~tactile_viewer.sources.lsl.ForceOutlet` (node forces, and the stress
when asked), stamped with the frame's receive time on LSL's clock. A frame
solved again (a slider moved) is not published twice; recordings played
back are not published (their frames were received long ago). The outlet is
made for the live source's skin and made again when another skin is shown.
"""

from __future__ import annotations

import logging

from ..sources.live import LiveSource
from ..sources.lsl import FORCE_TYPE, STRESS_TYPE, ForceOutlet, clock_offset
from ..sources.source import Signal
from .solved import Solved

log = logging.getLogger(__name__)

__all__ = ["ForcePublishing"]


class ForcePublishing:
    """Publishes the forces of every solved live frame over LSL while :attr:`enabled`.

    Parameters
    ----------
    model : ViewerModel
        Whose ``solved`` frames are published (on the model's thread).
    name : str
        The streams' LSL name (default ``"tactile-viewer"``).

    Attributes
    ----------
    changed : Signal
        Emitted when publishing starts, stops, opens an outlet or fails.
    published : int
        Frames published since it was switched on.
    failures : int
        Frames that could not be published (the last reason in :attr:`error`).
    """

    def __init__(self, model, *, name: str = "tactile-viewer"):
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"name must be a non-empty string, got {name!r}")
        self.model = model
        self.name = name
        self.enabled = False
        self.stress = False
        self.outlet: ForceOutlet | None = None
        self.published = 0
        self.failures = 0
        self.error = ""
        self.changed = Signal()
        self._offset: float | None = None  # receive clock to LSL clock, for the source shown
        self._last_time: float | None = None  # receive time of the frame published last
        model.solved.connect(self._solved)
        model.recording_changed.connect(self._source_changed)

    def start(self, *, stress: bool = False) -> None:
        """Publish from the next solved live frame on; ``stress`` adds the ``Tactile`` stream.

        Raises
        ------
        ValueError
            For a ``stress`` that is not True or False.
        RuntimeError
            When liblsl cannot make an outlet (the message says why); nothing is published then.
        """
        if not isinstance(stress, bool):
            raise ValueError(f"stress must be True or False, got {stress!r}")
        self.enabled, self.stress = True, stress
        self.published = self.failures = 0
        self.error = ""
        if self.outlet is not None and self.outlet.publishes_stress != stress:
            self._close()
        try:
            self._ensure_outlet()
        except Exception:
            self.enabled = False
            raise
        finally:
            self.changed.emit()

    def stop(self) -> None:
        """Stop publishing and withdraw the streams."""
        self.enabled = False
        self._close()
        self.changed.emit()

    def status(self) -> str:
        """What is published, for the live bar ("" when off)."""
        if not self.enabled:
            return ""
        if self.outlet is None:
            return f"LSL: publishing as {self.name!r} once a live board shows"
        streams = FORCE_TYPE + (f" + {STRESS_TYPE}" if self.outlet.publishes_stress else "")
        text = f"LSL: {self.published} frames published as {self.name!r} ({streams})"
        if self.failures:
            text += f"; {self.failures} not published: {self.error}"
        return text

    def _live_source(self) -> LiveSource | None:
        source = self.model.source
        return source if isinstance(source, LiveSource) else None

    def _ensure_outlet(self) -> ForceOutlet | None:
        source = self._live_source()
        if source is None:
            return None
        # named after the board and its size: a consumer recovers across a restart of the window
        # only onto the same board's stream of the same shape (another board, even of the same
        # shape, gets an outlet of its own)
        source_id = f"{self.name}:{source.url}:{source.grid.size}"
        outlet = self.outlet
        if outlet is not None and outlet.grid.key == source.grid.key and outlet.source_id == source_id:
            return outlet
        self._close()
        self.outlet = ForceOutlet(source.grid, name=self.name, source_id=source_id, stress=self.stress)
        self._offset = clock_offset(source.now)
        self.changed.emit()
        return self.outlet

    def _close(self) -> None:
        outlet, self.outlet = self.outlet, None
        self._last_time = None
        if outlet is not None:
            outlet.close()

    def _source_changed(self) -> None:
        # another source (or the same one with another solver): its clock is measured anew
        self._offset = None
        self._last_time = None
        source = self._live_source()
        if self.enabled and source is not None:
            self._offset = clock_offset(source.now)

    def _solved(self, solved: Solved) -> None:
        if not self.enabled or not self.model.live:
            return
        if self._last_time is not None and solved.time <= self._last_time:
            return  # the same frame solved again with other parameters: its stamp was published
        try:
            outlet = self._ensure_outlet()
            if outlet is None:
                return
            if self._offset is None:
                self._offset = clock_offset(self._live_source().now)
            outlet.push(solved.result.forces, stamp=solved.time + self._offset,
                        stress=solved.stress if outlet.publishes_stress else None)
        except Exception as exc:  # publishing must never cost the window its frames
            self.failures += 1
            self.error = str(exc)
            if self.failures == 1:
                log.exception("publishing frame %s over LSL failed", solved.frame)
                self.model.message.emit("warning", "LSL publishing failed",
                                        f"frame {solved.frame}: {exc}. Publishing goes on with the next "
                                        "frames; the live bar counts the frames not published.")
            self.changed.emit()
            return
        self._last_time = solved.time
        self.published += 1
