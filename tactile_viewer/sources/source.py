"""Where frames come from: one small interface for a recording and a live board. No Qt.

A :class:`Source` has a geometry (``grid``), a ``label`` for people,
``start``/``stop``, a ``state``, and two events: ``frame_arrived`` (a new frame
is waiting in :meth:`Source.take_latest`; it may fire on any thread) and
``state_changed``. The viewer's model follows any source the same way, and
any source can record the frames it produces (:meth:`Source.start_recording`).

:class:`RecordingSource` plays a recording on its own clock (seek, step,
play, loop); the live board is :class:`tactile_viewer.sources.live.LiveSource`
and its transports. A new kind of source (a network stream) is one subclass.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver import SensorGrid

from ..io.mcap_writer import Recorder
from ..io.recording import Recording, RecordingError, StressCalibration
from .playback import PlaybackClock

__all__ = ["Signal", "SourceFrame", "Source", "RecordingSource"]


class Signal:
    """A minimal callback list: ``connect(fn)``, ``disconnect(fn)``, ``emit(*args)``."""

    def __init__(self):
        self._slots = []

    def connect(self, slot):
        self._slots.append(slot)

    def disconnect(self, slot):
        self._slots.remove(slot)

    def emit(self, *args):
        for slot in list(self._slots):
            slot(*args)


@dataclass(frozen=True)
class SourceFrame:
    """One frame of stresses as a source produced it.

    Attributes
    ----------
    stress : (m,) ndarray
        Pascals (calibrated and tared for a live board).
    t : float
        Seconds: the recording's time stamp, or the receive time since a
        live reader started.
    index : int or None
        The frame's index in a recording, a live frame's unwrapped sequence
        number, None when the source numbers nothing (text frames).
    raw : (m,) ndarray or None
        The values as the source received them, before calibration (what a
        recording stores); None when ``stress`` is what was received.
    """

    stress: np.ndarray
    t: float
    index: int | None
    raw: np.ndarray | None = None


class Source:
    """What every source of frames offers. Subclasses produce frames through :meth:`_publish`.

    Parameters
    ----------
    label : str
        What the source is, for people (a file path, a URL).
    grid : SensorGrid
        The geometry of every frame it produces.

    Attributes
    ----------
    live : bool
        Class constant: frames arrive on another thread at the source's own
        pace (the viewer then solves only the newest, once the last is shown).
    frame_arrived : Signal
        Emitted with no arguments when a new frame waits in :meth:`take_latest`
        (once until it is taken: a display may skip frames, the recorder never
        does). From the thread that produced the frame.
    state_changed : Signal
        Emitted when :attr:`state` changes.
    frames_produced : Signal
        Emitted with the list of frames just produced, every one in order
        (none skipped, as the recorder gets them), from the thread that
        produced them, after the recorder has them: what a consumer that must
        see each frame (``tactile-stream``) follows.
    message : Signal
        News for people, emitted as ``(level, title, text)`` with level
        ``"info"``, ``"warning"`` or ``"error"``: a recording saved, a tare
        that looked loaded, a recording that could not be completed.
    recorder : Recorder or None
        Where every produced frame is written, while recording.
    """

    live = False
    raw_dtype = "float64"  # how its raw values are recorded: as they arrive

    def __init__(self, label: str, grid: SensorGrid):
        self.label = label
        self.grid = grid
        self.frame_arrived = Signal()
        self.state_changed = Signal()
        self.frames_produced = Signal()
        self.message = Signal()
        self.recorder: Recorder | None = None
        self.published = 0  # frames produced so far (each counted once it went to the recorder)
        self.clock_origin = time.time()  # UNIX seconds of the frames' time 0
        self._state = "stopped"
        self._latest: SourceFrame | None = None
        self._notified = False
        self._lock = threading.Lock()

    @property
    def state(self) -> str:
        """``"stopped"``, ``"running"``, or a subclass's own (``"connected"``, ``"reconnecting"``)."""
        return self._state

    def _set_state(self, state: str) -> None:
        if state != self._state:
            self._state = state
            self.state_changed.emit()

    def start(self) -> None:
        """Begin producing frames."""
        self._set_state("running")

    def stop(self) -> None:
        """Stop producing frames and close any recording (its file stays complete)."""
        self._set_state("stopped")
        self.stop_recording()

    def take_latest(self) -> SourceFrame | None:
        """The newest frame not yet taken (None if none arrived since)."""
        with self._lock:
            frame, self._latest, self._notified = self._latest, None, False
        return frame

    def recorded_calibration(self) -> StressCalibration:
        """How the raw values of its frames become stresses (recorded beside them)."""
        return StressCalibration.identity(self.grid.size)

    def start_recording(self, path, *, flush_interval: float = 1.0) -> Recorder:
        """Write every frame produced from now on to ``path`` (``.mcap``): raw values and calibration.

        Raises
        ------
        ValueError
            For a path not ending in ``.mcap``.
        OSError
            When the file cannot be created.
        """
        recorder = Recorder(path, self.grid, calibration=self.recorded_calibration(), dtype=self.raw_dtype,
                            flush_interval=flush_interval, description=self.label,
                            clock_origin=self.clock_origin)
        self.recorder = recorder
        return recorder

    def stop_recording(self) -> Path | None:
        """Close the recording; the path written, or None (none running, no frame, or it failed).

        :attr:`message` says what happened: a full disk or a vanished folder
        loses nothing already written, and the source goes on.
        """
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return None
        try:
            written = recorder.close()
        except (OSError, ValueError) as exc:
            self._recording_failed(recorder, exc, "Recording not completed")
            return None
        if written is None:
            self.message.emit("info", "nothing recorded", f"no frame arrived; {recorder.path} not written")
        elif recorder.dropped:
            self.message.emit("warning", "recording saved",
                              f"{written}: {recorder.dropped} frames not recorded (the disk was slower than "
                              "the board)")
        else:
            self.message.emit("info", "recording saved", str(written))
        return written

    def _recording_failed(self, recorder: Recorder, exc: Exception, title: str) -> None:
        # a failed write ends the recording, never the source: say what the file keeps
        if self.recorder is recorder:
            self.recorder = None
        recorder.abandon()
        self.message.emit("error", title,
                          f"{recorder.path}: {getattr(exc, 'strerror', None) or exc}. The frames written "
                          f"before the error ({recorder.written}) are in the file; the live view goes on.")

    def _to_recorder(self, write) -> None:
        # ``write(recorder)`` while recording; a failed write ends the recording, never the source
        recorder = self.recorder
        if recorder is not None:
            try:
                write(recorder)
            except (OSError, ValueError) as exc:
                self._recording_failed(recorder, exc, "Recording stopped")

    def _record(self, recorder: Recorder, seq: int, t: float, values) -> None:
        if not recorder.add(seq, t, values) and recorder.dropped == 1:
            self.message.emit("warning", "Recording falls behind",
                              f"{recorder.path}: the disk takes frames slower than the board sends them; "
                              "frames that find the recorder's queue full are not recorded (counted, and "
                              "the count is said when the recording stops)")

    def _tick_recording(self, now: float) -> None:
        # frames waiting for their chunk go to disk on time even when no new frame comes
        self._to_recorder(lambda recorder: recorder.tick(now))

    def _publish(self, frames: list[SourceFrame]) -> None:
        # every frame to the recorder, the newest to whoever follows the source
        if not frames:
            return
        for frame in frames:
            seq = frame.index if frame.index is not None else self.published
            values = frame.stress if frame.raw is None else frame.raw
            self._to_recorder(lambda recorder: self._record(recorder, seq, frame.t, values))  # noqa: B023 (called now)
            # counted once handed to the recorder: a stop_recording that follows the count keeps it
            self.published += 1
        self.frames_produced.emit(frames)
        with self._lock:
            self._latest = frames[-1]
            notify = not self._notified
            self._notified = True
        if notify:
            self.frame_arrived.emit()


class RecordingSource(Source):
    """A recording played on its own clock: seek, step, play at a speed, loop.

    Frames are produced on the thread that seeks (the GUI's). Playback shows
    the frame whose time has come (:class:`~tactile_viewer.sources.playback.PlaybackClock`),
    so slow drawing skips frames instead of stretching time; whoever owns the
    timer calls :meth:`advance`.

    Parameters
    ----------
    recording : Recording
    path : path-like, optional
        The file it came from.
    """

    def __init__(self, recording: Recording, path=None):
        self.path = Path(path) if path is not None else None
        super().__init__(str(self.path) if self.path else recording.description, recording.grid)
        self.recording = recording
        self.position = 0
        self.speed = 1.0
        self.loop = False
        self._clock = PlaybackClock(recording.t)
        if recording.received is not None:
            self.clock_origin = recording.received
        if recording.calibration is not None:
            self.raw_dtype = recording.frames.raw_dtype.name
        self.loaded_calibration = recording.calibration  # with the tares taken while recording

    def recorded_calibration(self) -> StressCalibration:
        return self.recording.calibration or super().recorded_calibration()

    def recalibrate(self, calibration: StressCalibration) -> None:
        """Show the recording through ``calibration`` (a tare retaken or cleared) from the current frame.

        The file is not changed: it keeps the raw values.

        Raises
        ------
        ValueError
            When the recording keeps no raw values (NPZ, CSV).
        """
        self.recording = self.recording.recalibrated(calibration)
        self.seek(self.position)

    @property
    def name(self) -> str:
        """The file's name, or "recording"."""
        return self.path.name if self.path else "recording"

    def __len__(self) -> int:
        return len(self.recording)

    def frame(self, index: int) -> SourceFrame:
        """Frame ``index`` of the recording (nothing is produced)."""
        frames = self.recording.frames
        raw = frames.raw(index) if self.recording.calibration is not None else None
        return SourceFrame(frames[index], float(self.recording.t[index]), index, raw)

    def seek(self, index: int, *, now: float | None = None) -> None:
        """Produce frame ``index``; ``now`` (seconds) restarts the clock from it.

        Raises
        ------
        ValueError
            When ``index`` is outside the recording.
        """
        index = int(index)
        if not 0 <= index < len(self):
            raise ValueError(f"frame must be in [0, {len(self) - 1}], got {index}")
        try:
            frame = self.frame(index)
        except RecordingError as exc:
            # a damaged chunk of a recording: say so once and stop there, never on every tick
            self.pause()
            self.message.emit("error", "Frame not readable", str(exc))
            return
        self.position = index
        if now is not None:
            self._clock.restart(index, now)
        self._publish([frame])

    def play(self, now: float) -> None:
        """Play on from the current frame (from the first when at the end) as of ``now`` seconds."""
        if self.position == len(self) - 1:
            self.seek(0)
        self._clock.restart(self.position, now)
        self._set_state("playing")

    def pause(self) -> None:
        self._set_state("stopped")

    def set_speed(self, speed: float, now: float) -> None:
        """Play ``speed`` times real time from the current frame on."""
        if not speed > 0:
            raise ValueError(f"speed must be > 0, got {speed!r}")
        self.speed = float(speed)
        self._clock.restart(self.position, now)

    def advance(self, now: float) -> None:
        """While playing: produce the frame due at ``now`` seconds; stop at the end unless looping."""
        if self.state != "playing":
            return
        index, finished = self._clock.due(now, speed=self.speed, loop=self.loop)
        if index != self.position:
            self.seek(index)
        if finished:
            self.pause()
