"""What the scene shows: the :class:`Display` settings and their defaults for a new source.

No Qt. The settings are a frozen dataclass the model replaces as a whole
(:meth:`~tactile_viewer.model.viewer_model.ViewerModel.set_display`);
:func:`display_scales` picks readable arrow lengths and colour ranges from a
source's loads when it opens (and when a tare changes them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from solver.arguments import MAX_STRESS
from solver.checks import one_of

from ..sources.source import RecordingSource, Source

__all__ = ["Display", "display_scales", "MAPS", "MAX_SMOOTHING", "HIDE_BELOW", "RANGE_MARGIN"]

# the map's fixed colour range over the most loaded frame's normal-only peak pressure (display_scales)
RANGE_MARGIN = 1.75
MAX_SMOOTHING = 10.0  # seconds: past any contact a lab follows
MAPS = ("pressure", "stress", "none")
HIDE_BELOW = 0.02  # default "hide below": this fraction of the largest node force of a new source


@dataclass(frozen=True)
class Display:
    """What the scene shows.

    Attributes
    ----------
    map : {"pressure", "stress", "none"}
        Reconstructed normal pressure (``Fz / pitch^2``) or measured sensor stress.
    arrows, resultant : bool
        Per-node force arrows; the resultants (one per contact, at its own
        load centroid; one for the whole frame when the solve found no contacts).
    arrow_scale : float
        Arrow length per newton, metres per newton.
    resultant_scale : float
        Length of the resultant's arrow per newton, metres per newton.
    threshold : float
        Arrows of nodes with ``|F|`` below this many newtons are hidden
        (``|(Fx, Fy)|`` for in-plane arrows).
    auto_range : bool
        Colour range follows each frame, ending on a round number at most 4/3
        of its largest value (and of its most negative, below zero; see
        ``tactile_viewer.render.scene.bar_top``); otherwise ``0 .. range_max``.
    range_max : float
        Upper end of the fixed colour range, pascals.
    colormap : str
        Colour map of the pressure or stress map, one of :attr:`COLORMAPS`
        (perceptually uniform, and ``gray`` for print).
    arrow_auto_range : bool
        The arrows' colour range follows each frame (``0 ..`` a round number at
        most 4/3 of its largest shown force); otherwise ``0 .. arrow_range_max``,
        the same for every frame.
    arrow_range_max : float
        Upper end of the arrows' fixed colour range, newtons.
    in_plane : bool
        Arrows (and resultants) show only ``(Fx, Fy)``, flat on the surface:
        the Top view's shear picture. The Top camera button switches it on,
        the Iso button off.
    in_plane_gain : float
        In-plane arrows and resultants are drawn this many times longer than
        3-D ones (shear is a fraction of the normal force); the scales the
        scene states include it. Positive.
    axes : bool
        x and y ticks in millimetres beside the skin and the direction
        convention (0 deg = +x, 90 deg = +y) at its corner.
    taxel_ids : bool
        Each taxel's node index (from 0, as everywhere) on its square.
    smoothing : float
        Time constant, seconds, of the exponential smoothing of the node
        forces drawn (arrows and pressure map) over frame time; 0 is off
        (the default). Smoothed forces lag the data by about this much and a
        step reaches 63% of its height after it. Never applied to exports,
        the read-out, the contacts or the status line.
    """

    COLORMAPS: ClassVar[tuple] = ("viridis", "cividis", "plasma", "inferno", "magma", "gray")

    map: str = "pressure"
    arrows: bool = True
    resultant: bool = True
    arrow_scale: float = 0.01
    resultant_scale: float = 0.01
    threshold: float = 0.0
    auto_range: bool = True
    range_max: float = 50e3
    colormap: str = "viridis"
    arrow_auto_range: bool = True
    arrow_range_max: float = 0.05
    in_plane: bool = False
    in_plane_gain: float = 2.0
    axes: bool = True
    taxel_ids: bool = False
    smoothing: float = 0.0

    CAMERAS: ClassVar[tuple] = ("top", "iso")

    def seen_from(self, camera: str) -> Display:
        """This display as a camera preset shows it: from ``"top"`` the arrows lie flat
        (``in_plane``: the shear alone), from ``"iso"`` they stand in 3-D.

        The one place of this rule: the window's camera buttons and menu, the
        headless screenshot and the movie all follow it.
        """
        one_of("camera", camera, self.CAMERAS)
        return replace(self, in_plane=camera == "top")

    def __post_init__(self):
        one_of("map", self.map, MAPS)
        one_of("colormap", self.colormap, self.COLORMAPS)
        for name in ("arrow_scale", "resultant_scale", "threshold", "range_max", "arrow_range_max",
                     "smoothing"):
            value = getattr(self, name)
            # bool is a number to Python, but never a scale a caller meant
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if self.smoothing > MAX_SMOOTHING:
            raise ValueError(f"smoothing must be at most {MAX_SMOOTHING:g} s, got {self.smoothing!r}")
        if not (isinstance(self.in_plane_gain, (int, float, np.integer, np.floating))
                and not isinstance(self.in_plane_gain, bool)
                and math.isfinite(self.in_plane_gain) and self.in_plane_gain > 0):
            raise ValueError(f"in_plane_gain must be finite and > 0, got {self.in_plane_gain!r}")
        for name in ("arrows", "resultant", "auto_range", "arrow_auto_range", "in_plane", "axes",
                     "taxel_ids"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False, got {value!r}")



def display_scales(source: Source, reconstructor) -> dict:
    """Readable default arrow lengths and colour ranges for a new source (``Display`` fields)."""
    grid = source.grid
    width = float(np.ptp(grid.positions[:, 0])) + grid.pitch
    if not isinstance(source, RecordingSource):
        # nothing seen yet: 50 mN per node spans three pitches, a 1 N total half the skin,
        # and 50 mN tops the arrows' fixed colour range
        return dict(arrow_scale=3 * grid.pitch / 0.05, resultant_scale=width / 2, threshold=HIDE_BELOW * 0.05,
                    arrow_range_max=0.05)
    # on the recording's most loaded frame the largest node force spans about three pitches,
    # the total half the skin (each contact has its own resultant: with two, each must still
    # stand out of its contact's arrows); the fixed colour ranges hold every frame
    recording = source.recording
    if hasattr(recording.frames, "sample"):
        # an MCAP recording is read lazily: a frame from each of a few chunks, damaged ones skipped
        frames = recording.frames.sample()
    else:
        spread = np.linspace(0, len(recording) - 1, min(len(recording), 2048)).astype(int)
        frames = recording.frames[np.unique(spread)]
    # a frame the solver refuses (a value beyond MAX_STRESS) is reported when it is shown, not here
    frames = frames[np.all(np.abs(frames) <= MAX_STRESS, axis=1)]
    if not len(frames):
        return dict(arrow_scale=3 * grid.pitch / 0.05, resultant_scale=width / 2, threshold=HIDE_BELOW * 0.05,
                    arrow_range_max=0.05)
    loaded = int(np.argmax(np.abs(frames).sum(axis=1)))
    first = reconstructor.solve_normal(frames[loaded]).forces[:, 2]
    peak = float(np.abs(first).max()) or 1.0
    total = abs(float(first.sum())) or peak
    # arrows under 2% of the largest node force are noise more often than load: hidden by default.
    # The arrows' fixed colour range: the full solve concentrates a contact's load on fewer nodes
    # than this normal-only one (the four samples' largest node force over every frame is 1.24 to
    # 1.73 times `peak`), so 1.5 times it; a stronger node shows in the top colour
    # The map's fixed colour range: the pressure the map shows is the full solve's, which concentrates
    # the load more than this normal-only one (set at 1 times it, the core saturated on 16 to 60 of
    # 30 to 60 frames of every sample); their frames' peak pressure is up to 1.66 times the most
    # loaded frame's normal-only peak, so RANGE_MARGIN times it. The stress map shares the range.
    return dict(arrow_scale=3 * grid.pitch / peak, resultant_scale=width / 2 / total,
                range_max=max(float(np.abs(frames).max()), RANGE_MARGIN * peak / grid.pitch**2, 1.0),
                threshold=HIDE_BELOW * peak, arrow_range_max=1.5 * peak)
