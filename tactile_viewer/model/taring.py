"""Retaking, clearing or restoring the tare of a source: the zero its stresses are measured from.

No Qt. :meth:`~tactile_viewer.model.viewer_model.ViewerModel.retare` is the one
way every caller changes a tare (the window's Recording menu, the live bar's
Tare); :func:`retare_source` does it to the source. A recording's file keeps
its raw values and is not changed.
"""

from __future__ import annotations

import numpy as np

from ..io.recording import Tare
from ..sources.live import LiveSource
from ..sources.source import RecordingSource, Source

__all__ = ["keeps_raw_values", "retare_source"]


def keeps_raw_values(source: Source | None) -> bool:
    """``source`` is a recording that keeps raw values (MCAP): its tare can be retaken, cleared, restored."""
    return isinstance(source, RecordingSource) and source.recording.calibration is not None


def retare_source(source: Source | None, how: str, *, frames: int = 50) -> str:
    """Change the tare of ``source``; what was done, for the status line.

    A live board takes ``"here"`` only: the mean of its next ``frames``
    frames becomes the zero of every taxel. For a recording, see
    :meth:`~tactile_viewer.model.viewer_model.ViewerModel.retare`.

    Raises
    ------
    ValueError
        When no recording with raw values (MCAP) or live board is given, or for an unknown ``how``.
    """
    if isinstance(source, LiveSource):
        if how != "here":
            raise ValueError(f"a live board's tare is taken 'here', got {how!r}")
        source.calibration.tare(frames)
        return f"taring: averaging the next {frames} frames"
    if not keeps_raw_values(source):
        raise ValueError("only a recording that keeps raw values (a live recording, .mcap) can be "
                         "re-tared")
    if how not in ("here", "clear", "recorded"):
        raise ValueError(f"how must be 'here', 'clear' or 'recorded', got {how!r}")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ValueError(f"frames must be a positive integer, got {frames!r}")
    calibration = source.recording.calibration
    if how == "recorded":
        calibration = source.loaded_calibration
        text = f"the tares taken while recording ({len(calibration.tares)})"
    elif how == "clear":
        calibration = calibration.retared(None)
        text = "no tare"
    else:
        rows = np.arange(source.position, min(source.position + frames, len(source)))
        untared = calibration.retared(None).apply(source.recording.frames.raw(rows), rows)
        taken = float(source.recording.t[rows[0]])
        calibration = calibration.retared(Tare(0, untared.mean(axis=0), taken, len(rows)))
        text = f"tare from frames {rows[0]} to {rows[-1]}"
    source.recalibrate(calibration)
    return text
