"""A movie's settings and their checks: its type, frames, rate, size, parameters, camera and display. No Qt.

No pyvista either: the command line (``tactile-viewer REC --movie OUT``) and the
window's *Export movie...* dialog check their options here, with their own names
in the messages, before anything is solved or rendered;
:class:`~tactile_viewer.render.movie.MovieExport` checks its arguments with the
same functions.

- Frames ``start .. stop - 1`` are shown, numbered from 0 as everywhere:
  ``stop`` is **exclusive** (as in a Python slice), so ``start=0,
  stop=len(recording)`` is the whole recording.
- ``.mp4``, ``.mkv`` and ``.avi`` are H.264 videos (width and height must be
  even); ``.gif`` is an animated GIF (at most :data:`GIF_MAX_FPS` frames per
  second).
"""

from __future__ import annotations

import math
from pathlib import Path

from solver.checks import real_number, shown, whole_number

from ..io.recording import Recording
from ..sources.source import RecordingSource
from .display import Display
from .shear_parameters import MAX_SHEAR_RATIO
from .viewer_model import ViewerModel

__all__ = ["default_display", "movie_kind", "check_frame", "check_frames", "check_fps", "check_size",
           "check_movie_parameters", "check_camera", "VIDEO_SUFFIXES", "GIF_SUFFIX",
           "DEFAULT_FPS", "DEFAULT_SIZE", "GIF_MAX_FPS", "GIF_MAX_BYTES"]

VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi")
GIF_SUFFIX = ".gif"
DEFAULT_FPS = 30.0
DEFAULT_SIZE = (1200, 800)  # as --screenshot
# a GIF's frame delay is a whole number of hundredths of a second, and browsers slow
# down delays under 2 hundredths: faster GIFs would not play at the rate asked for
GIF_MAX_FPS = 50.0
# a GIF holds every frame (one byte a pixel) until it is closed: 1 GiB is about
# 1100 frames of 1200 x 800, 37 s at 30 fps; longer movies belong in a video
GIF_MAX_BYTES = 1 << 30


# -- argument checks ------------------------------------------------------------------------------


def movie_kind(path, *, name: str = "path") -> str:
    """``"video"`` or ``"gif"``, from the file name's ending (either case).

    Raises
    ------
    ValueError
        For any other ending, naming ``name``, the endings accepted and the one received.
    """
    suffix = Path(path).suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return "video"
    if suffix == GIF_SUFFIX:
        return "gif"
    accepted = ", ".join((*VIDEO_SUFFIXES, GIF_SUFFIX))
    raise ValueError(f"{name} must end in {accepted} (the movie's type), got {str(path)!r}")


def check_frame(count: int, frame, *, name: str = "frame", what: str = "the frame") -> int:
    """One frame of a ``count``-frame recording, numbered from 0, checked.

    Parameters
    ----------
    count : int
        Frames in the recording.
    frame : int
        The frame, from 0 to ``count - 1``.
    name : str
        What it is called in the message (the command line's ``--frame``).
    what : str
        What the frame is for, in the message ("the first frame").

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Naming ``name``, its bounds for this recording and the value received.
    """
    if count < 1:
        raise ValueError(f"the recording has no frames: {name} cannot be chosen")
    try:
        return whole_number(name, frame, low=0, high=count - 1)
    except ValueError:
        raise ValueError(f"{name} must be a whole number from 0 to {count - 1} ({what}, numbered from 0; the "
                         f"recording has {count} frames), got {shown(frame)}") from None


def check_frames(count: int, start=0, stop=None, *, names=("start", "stop")) -> range:
    """The frames a movie of a ``count``-frame recording shows: ``range(start, stop)``.

    Parameters
    ----------
    count : int
        Frames in the recording.
    start : int
        First frame, from 0.
    stop : int or None
        The frame after the last one (exclusive); None: ``count``, the end.
    names : (2,) tuple of str
        What the two are called in messages (the command line's ``--start``, ``--stop``).

    Raises
    ------
    ValueError
        Naming the argument, its bounds for this recording and the value received.
    """
    if count < 1:
        raise ValueError("the recording has no frames: there is nothing to make a movie of")
    first, after = names
    start = check_frame(count, start, name=first, what="the first frame")
    if stop is None:
        return range(start, count)
    try:
        stop = whole_number(after, stop, low=start + 1, high=count)
    except ValueError:
        raise ValueError(f"{after} must be a whole number from {start + 1} to {count} (exclusive: the movie "
                         f"ends before frame {after}; the recording has {count} frames and {first} is "
                         f"{start}), got {shown(stop)}") from None
    return range(start, stop)


def check_fps(fps, kind: str = "video", *, name: str = "fps") -> float:
    """Frames per second of a movie, checked.

    Parameters
    ----------
    fps : float
        Finite and > 0; at most :data:`GIF_MAX_FPS` for a GIF.
    kind : {"video", "gif"}
    name : str
        What it is called in the message.

    Raises
    ------
    ValueError
        Naming ``name``, the rule and the value received.
    """
    if kind == "gif":
        return real_number(name, fps, rule=f"> 0 and at most {GIF_MAX_FPS:g} for a GIF (its frame delays "
                           "are hundredths of a second; players slow faster GIFs down)",
                           valid=lambda v: 0 < v <= GIF_MAX_FPS)
    return real_number(name, fps, rule="finite and > 0", valid=lambda v: 0 < v < math.inf)


def check_size(size, kind: str = "video", *, name: str = "size") -> tuple:
    """The size of a movie's frames, checked.

    Parameters
    ----------
    size : (2,) tuple of int
        Width and height in pixels, whole numbers from 16 to 8192; even for a video
        (yuv420p halves the colour resolution, so H.264 needs even sides, and imageio
        would otherwise scale the frames).
    kind : {"video", "gif", "image"}
    name : str
        What it is called in the message.

    Returns
    -------
    (2,) tuple of int

    Raises
    ------
    ValueError
        Naming ``name``, the rule and the value received.
    """
    try:
        width, height = size
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (width, height) in pixels, got {shown(size)}") from None
    width = whole_number(f"{name} width", width, low=16, high=8192, unit="of pixels ")
    height = whole_number(f"{name} height", height, low=16, high=8192, unit="of pixels ")
    if kind == "video" and (width % 2 or height % 2):
        raise ValueError(f"{name} must have an even width and height for a video (H.264, yuv420p), "
                         f"got {width} x {height}")
    return width, height


def check_movie_parameters(shear_ratio, shear_direction, *, names=("shear_ratio", "shear_direction"),
                     degrees: bool = False) -> tuple:
    """The parameters a movie is solved with: both None (found for each frame) or both given (fixed).

    Parameters
    ----------
    shear_ratio : float or None
        In ``[0, MAX_SHEAR_RATIO]``.
    shear_direction : float or None
        Finite; radians, or degrees with ``degrees``.
    names : (2,) tuple of str
        What the two are called in messages (the command line's ``--shear-ratio``, ``--shear-direction``).
    degrees : bool
        ``shear_direction`` is in degrees (the command line's).

    Returns
    -------
    (ratio, direction) : tuple of float or None
        The direction in radians, in ``[-pi, pi]``; ``(None, None)`` for automatic.

    Raises
    ------
    ValueError
        Naming the argument, the rule and the value received.
    """
    ratio_name, direction_name = names
    if shear_ratio is None and shear_direction is None:
        return None, None
    if shear_ratio is None or shear_direction is None:
        raise ValueError(f"{ratio_name} and {direction_name} must be given together (fixed parameters) or "
                         f"both be None (automatic), got {shown(shear_ratio)} and {shown(shear_direction)}")
    ratio = real_number(ratio_name, shear_ratio, rule=f"in [0, {MAX_SHEAR_RATIO}]",
                        valid=lambda v: 0 <= v <= MAX_SHEAR_RATIO)
    direction = real_number(direction_name, shear_direction,
                            rule=f"finite {'degrees' if degrees else 'radians'}", valid=math.isfinite)
    if degrees:
        direction = math.radians(direction)
    return ratio, math.remainder(direction, 2 * math.pi)


def check_camera(camera, *, name: str = "camera"):
    """A movie's camera, checked: a preset of :attr:`Display.CAMERAS` or a VTK camera (copied whole).

    Raises
    ------
    ValueError
        Naming ``name``, what is accepted and the value received.
    """
    if isinstance(camera, str):
        if camera in Display.CAMERAS:
            return camera
    elif callable(getattr(camera, "DeepCopy", None)) and callable(getattr(camera, "GetParallelScale", None)):
        return camera
    raise ValueError(f"{name} must be one of {Display.CAMERAS} or a vtkCamera (the window's, copied whole), "
                     f"got {shown(camera)}")


# -- what the frames show --------------------------------------------------------------------------


def default_display(recording: Recording, solver, *, display_map: str = "pressure",
                    camera: str = "iso") -> Display:
    """The window's display settings for a recording seen from a camera preset.

    The arrow lengths, hidden arrows and colour ranges a window would pick for the recording,
    with both colour ranges (the map's and the arrows') fixed for the whole movie so colours
    compare across frames, as seen from ``camera`` (:meth:`Display.seen_from`: in-plane arrows
    from the top, 3-D ones from ``"iso"``).

    Raises
    ------
    ValueError
        ``camera`` is not a preset, or ``display_map`` not a map (named, with the value received).
    """
    seen = Display().seen_from(camera)  # checked before anything is solved
    model = ViewerModel()  # no dispatch: nothing is solved or scheduled
    model.set_source(RecordingSource(recording), solver)
    model.set_display(map=display_map, auto_range=False, arrow_auto_range=False, in_plane=seen.in_plane)
    return model.display
