"""The texts the viewer shows: a geometry named for people, the kernels' help, the window's title.

No Qt. The window's parameters panel and the command lines (``tactile-viewer``,
``tactile-tradeoff``) show the same words; the window sets its title and
warnings from here.
"""

from __future__ import annotations

from pathlib import Path

from solver import SensorGrid

from ..io.recording import Recording
from ..sources.source import Source

__all__ = ["KERNEL_HELP", "geometry_text", "window_title", "recording_warnings"]

KERNEL_HELP = "layer: elastomer layer bonded to a rigid hull (default); cell/point: half-space"


def geometry_text(grid: SensorGrid) -> str:
    """One line naming a geometry for people: taxels, pitch, thickness, nu, taxel size.

    Examples
    --------
    >>> geometry_text(SensorGrid.regular(16, 12, 2e-3, 1.5e-3, poisson_ratio=0.45, sensor_size=1e-3))
    '16x12 taxels, pitch 2 mm, thickness 1.5 mm, nu 0.45, taxel 1 mm'
    """
    taxels = f"{grid.shape[1]}x{grid.shape[0]} taxels" if len(grid.shape) == 2 else f"{grid.size} taxels"
    size = f"taxel {grid.sensor_size * 1e3:g} mm" if grid.sensor_size > 0 else "point sensors"
    return (f"{taxels}, pitch {grid.pitch * 1e3:g} mm, thickness {grid.thickness * 1e3:g} mm, "
            f"nu {grid.poisson_ratio:g}, {size}")


def _name(source: Source) -> str:
    return source.path.name if getattr(source, "path", None) else "recording"


def window_title(source: Source | None, recording: Recording | None, *, recording_to: str = "",
                 disconnected: bool = False) -> str:
    """The window's title: what is shown and its state.

    The title keeps saying it after the status line has moved on (a live
    board recorded to ``recording_to``, a board disconnected, a damaged file).
    """
    if source is None:
        return "tactile-viewer"
    if disconnected:
        return f"tactile-viewer - {source.label} (disconnected)"
    if source.live:
        return f"tactile-viewer - live: {source.label}" + (
            f" - \u25cf REC {Path(recording_to).name}" if recording_to else "")
    return (f"tactile-viewer - {_name(source)}"
            + (" (damaged)" if recording is not None and recording.damage else ""))


def recording_warnings(source: Source | None, recording: Recording | None) -> list[tuple[str, str]]:
    """``(title, text)`` of each warning a recording opened with: cut short, damaged."""
    warnings = []
    if recording is not None and recording.truncated:
        warnings.append(("Recording cut short:",
                         f"{_name(source)} ends at its last complete chunk or row (a crash or a full disk "
                         "while it was written); every frame before is kept"))
    if recording is not None and recording.damage:
        warnings.append(("Recording damaged:", f"{_name(source)}: " + "; ".join(recording.damage)))
    return warnings
