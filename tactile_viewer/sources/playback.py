"""The playback clock of a recording: which frame is due now. No Qt.

Playback follows the recording's own timestamps at a chosen speed, so drawing
slower than the recording skips frames instead of stretching time.
:class:`~tactile_viewer.sources.source.RecordingSource` asks :meth:`PlaybackClock.due`
each time its owner's timer advances it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PlaybackClock"]


class PlaybackClock:
    """Maps wall-clock time to the frame of a recording that is due.

    Parameters
    ----------
    t : (T,) ndarray
        The recording's frame times, seconds, non-decreasing.
    """

    def __init__(self, t):
        self.t = np.asarray(t, dtype=float)
        if self.t.ndim != 1 or self.t.size == 0:
            raise ValueError(f"t must be a non-empty list of frame times, got shape {self.t.shape}")
        self._origin = (0.0, float(self.t[0]))  # (wall clock, recording time) at the last restart

    def restart(self, frame: int, now: float) -> None:
        """Play on from ``frame`` as of wall-clock time ``now`` (seconds)."""
        self._origin = (float(now), float(self.t[frame]))

    def due(self, now: float, *, speed: float = 1.0, loop: bool = False) -> tuple[int, bool]:
        """The frame due at wall-clock time ``now``, and whether playback has reached the end.

        Looping, the recording repeats with one mean frame interval after its
        last frame; otherwise it stops on the last frame.
        """
        t = self.t
        wall, start = self._origin
        position = start + (now - wall) * speed
        looping = loop and t.size > 1
        if looping and position > t[-1]:
            period = (t[-1] - t[0]) * t.size / (t.size - 1)
            if period > 0:
                position = t[0] + (position - t[0]) % period
        index = int(min(max(t.searchsorted(position, side="right") - 1, 0), t.size - 1))
        return index, index == t.size - 1 and not looping
