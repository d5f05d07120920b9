"""What ``tactile-viewer FILE --info`` prints about a recording: the facts of the file, nothing solved.

No Qt.
"""

from __future__ import annotations

import datetime
import math

import numpy as np

from .recording import Recording, RecordingError

__all__ = ["facts"]


def _clock(unix: float) -> str:
    # "2023-11-14 22:13:20.000 UTC (1700000000.000000 s)"
    when = datetime.datetime.fromtimestamp(unix, datetime.UTC)
    return f"{when:%Y-%m-%d %H:%M:%S}.{when.microsecond // 1000:03d} UTC ({unix:.6f} s)"


def facts(recording: Recording) -> list[str]:
    """What ``tactile-viewer FILE --info`` prints: one line per fact, nothing solved.

    ``frames``, ``span`` (seconds), ``sequence gaps`` (frames missing between
    the numbers received, and any repeated or reordered ones), ``first
    received`` and ``last received`` (UNIX seconds, the recorder's receive
    clock), ``cut short``, ``damage`` (what could not be read), ``checksums``
    (MCAP: the whole file read and every checksum checked), ``geometry`` and
    ``calibration``. What a format does not keep is said to be unknown.
    """
    grid = recording.grid
    lines = [f"frames {len(recording)}", f"span {float(recording.t[-1] - recording.t[0]):.3f} s"]
    try:
        sequence = recording.sequence()
    except RecordingError:  # a chunk fails its checksum: the checksums line says which
        lines.append("sequence gaps unknown (a damaged chunk holds some of them)")
    else:
        if sequence is None:
            lines.append("sequence gaps unknown (the file keeps no sequence numbers)")
        else:
            steps = np.diff(sequence)
            gaps = f"sequence gaps {int(np.sum(steps[steps > 1] - 1))}"
            backwards = int(np.sum(steps <= 0))
            lines.append(gaps + (f" ({backwards} repeated or reordered)" if backwards else ""))
    if recording.received is None:
        lines += ["first received unknown (the file keeps no receive clock)", "last received unknown"]
    else:
        # a date and clock time a person reads (UTC, to the millisecond), the UNIX seconds beside it
        lines += [f"first received {_clock(recording.received)}",
                  f"last received {_clock(recording.received + float(recording.t[-1]))}"]
    lines.append("cut short yes: it ends at its last complete chunk or row (a crash or a full disk)"
                 if recording.truncated else "cut short no")
    lines += [f"damage {what}" for what in recording.damage] or ["damage none found"]
    if hasattr(recording.frames, "verify"):
        problems = recording.frames.verify()
        checked = "every chunk's frames" + (" and the data section" if recording.frames.data_checksum else
                                            " (the file keeps no checksum of its data section)")
        lines += ([f"checksums fail: {what}" for what in problems] if problems else
                  [f"checksums good: {checked}, all read and checked"])
    size = (f"{grid.shape[1]}x{grid.shape[0]} taxels" if len(grid.shape) == 2
            else f"{grid.size} taxels (irregular)")
    lines.append(f"geometry {size}, pitch {grid.pitch * 1e3:g} mm, thickness {grid.thickness * 1e3:g} mm, "
                 f"poisson ratio {grid.poisson_ratio:g}, sensor size {grid.sensor_size * 1e3:g} mm")
    calibration = recording.calibration
    if calibration is None:
        lines.append("calibration none kept: the frames are stresses in pascals (NPZ, CSV and ROS 2 bags "
                     "opened with a layout keep no raw values)")
    else:
        fields = calibration.fields()
        def shown(value):
            if np.ndim(value) == 0:
                return f"{value:g}"
            return f"per taxel ({np.min(value):g} to {np.max(value):g})"
        def when(tare):  # a tare of a file that kept no time for it says so, not "nan s"
            return f"taken at {tare.t:.3f} s" if math.isfinite(tare.t) else "taken at an unknown time"
        tares = "; ".join(f"from frame {tare.from_frame} ({when(tare)}, {tare.frames} frames)"
                          for tare in calibration.tares) or "none"
        lines.append(f"calibration raw {recording.frames.raw_dtype.name} in {fields['units']}, "
                     f"gain {shown(fields['gain'])}, offset {shown(fields['offset'])}, tares: {tares}")
    return lines
