"""Movies of a recording: every frame drawn off screen by the window's own scene, written as a video or GIF.

No Qt here (pyvista and imageio only): the command line calls
:func:`write_movie`; the window drives a :class:`MovieExport` one frame at a
time from a timer on its GUI thread, because VTK must render on the thread
that owns its windows.

- Frames ``start .. stop - 1`` are written, numbered from 0 as everywhere:
  ``stop`` is **exclusive** (as in a Python slice), so ``start=0,
  stop=len(recording)`` is the whole recording.
- ``.mp4``, ``.mkv`` and ``.avi`` are H.264 videos (imageio's ffmpeg plugin,
  libx264, yuv420p: width and height must be even); ``.gif`` is an animated GIF
  (imageio's pillow plugin; at most
  :data:`~tactile_viewer.model.movie_settings.GIF_MAX_FPS` frames per second).
- Burnt into every frame (:func:`~tactile_viewer.render.frame_renderer.caption`):
  the frame number and time, the shear ratio and direction solved with (and
  whether they were found automatically or given), and the total normal and
  tangential force.
- The camera is a preset (``"iso"``, ``"top"``) or a whole VTK camera copied
  (projection, parallel scale, view angle, clipping: the window's view as it is);
  from a preset, the default display
  (:func:`~tactile_viewer.model.movie_settings.default_display`) follows
  :meth:`Display.seen_from` (Top lays
  the arrows flat, Iso stands them up), as the window's camera buttons do.
- The solver may be shared, the window's own included: the solvers keep no
  per-call state (see :mod:`tactile_viewer.model.series_solving`), so the movie solves with
  the model's while the model's worker thread solves the frame on screen.
- Every frame costs the same: the scene's actors and the caption are made once
  and updated in place, the solver is built once, and the writer streams (a
  video goes to an ffmpeg process frame by frame; a GIF keeps each frame
  quantized to 256 colours, one byte a pixel, and Pillow writes them when the
  file is closed, since a GIF cannot be appended to).
- The file is written under a temporary name in the target folder and renamed
  to the name asked for only when it is complete (and, for a video, once its
  frames have been counted back): a cancelled or failed export leaves nothing
  under that name and removes the temporary file.
"""

from __future__ import annotations

import errno
import logging
import os
import secrets
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from solver.checks import shown

from ..io.recording import Recording
from ..model.display import Display
from ..model.movie_settings import (
    DEFAULT_FPS,
    DEFAULT_SIZE,
    GIF_MAX_BYTES,
    GIF_SUFFIX,
    check_camera,
    check_fps,
    check_frames,
    check_movie_parameters,
    check_size,
    default_display,
    movie_kind,
)
from ..model.solved import Solved
from ..model.viewer_model import ViewerModel
from ..model.worker import Cancelled
from .frame_renderer import FrameRenderer

log = logging.getLogger(__name__)

__all__ = ["MovieExport", "MovieResult", "write_movie"]

# imageio-ffmpeg's quality 0..10 becomes libx264's crf as int((1 - q / 10) * 51): 6.5 is
# crf 17, where the burnt-in text and the colour bars' labels stay sharp
VIDEO_QUALITY = 6.5


@dataclass(frozen=True)
class MovieResult:
    """A movie written.

    Attributes
    ----------
    path : Path
        The file, under the name asked for.
    frames : int
        Frames written: one per recording frame from ``start`` to ``stop - 1``.
    size : (2,) tuple of int
        Width and height, pixels.
    fps : float
        Frames per second of the movie.
    frame_seconds : (frames,) ndarray
        Wall time of each frame: solve, render, grab and hand to the writer.
    finish_seconds : float
        Wall time of closing the file (a GIF is encoded then) and checking it.
    """

    path: Path
    frames: int
    size: tuple
    fps: float
    frame_seconds: np.ndarray
    finish_seconds: float

    @property
    def median_ms(self) -> float:
        """Median cost of one frame, milliseconds."""
        return 1e3 * float(np.median(self.frame_seconds)) if self.frames else 0.0

    def summary(self) -> str:
        """One line for people: ``wrote OUT: N frames, W x H, fps F, median X ms per frame``."""
        return (f"wrote {self.path}: {self.frames} frames, {self.size[0]} x {self.size[1]}, "
                f"fps {self.fps:g}, median {self.median_ms:.0f} ms per frame")


# -- the file ----------------------------------------------------------------------------------------


class _MovieFile:
    """A movie written under a temporary name beside ``path``; :meth:`commit` renames it, :meth:`discard`
    removes it. The temporary name keeps the ending: ffmpeg and Pillow pick the format by it."""

    def __init__(self, path: Path, *, kind: str, fps: float, frames: int):
        self.path, self.kind, self.fps = path, kind, fps
        self.written = 0
        folder = path.parent
        # checked here, before any rendering, with the folder named (ffmpeg would say little)
        if not folder.is_dir():
            raise FileNotFoundError(2, "the folder does not exist", str(folder))
        if not os.access(folder, os.W_OK):
            raise PermissionError(13, "the folder cannot be written", str(folder))
        if path.is_dir():
            raise IsADirectoryError(21, "is a folder", str(path))
        # hidden and unmistakable; created exclusively (with the user's umask), then written over
        self.temporary = folder / f".{path.name}.{secrets.token_hex(4)}.partial{path.suffix.lower()}"
        with open(self.temporary, "xb"):
            pass
        try:
            if kind == "video":
                import imageio.v2 as iio

                self._writer = iio.get_writer(
                    self.temporary, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                    quality=VIDEO_QUALITY, pixelformat="yuv420p",
                    # sides are even (check_size): no block padding, so imageio neither scales nor warns
                    macro_block_size=2, ffmpeg_log_level="error")
            else:
                import imageio.v3 as iio

                self._writer = iio.imopen(self.temporary, "w", plugin="pillow", extension=GIF_SUFFIX)
                delays = _gif_delays(fps, frames)
                # Pillow takes a list of delays for an animation, a number for a single frame (a list
                # for one frame fails when the file is closed)
                self._durations = delays if len(delays) > 1 else delays[0]
        except BaseException:
            self.temporary.unlink(missing_ok=True)
            raise

    def append(self, image: np.ndarray):
        if self.kind == "video":
            try:
                self._writer.append_data(image)
            except OSError as exc:  # ffmpeg went away: its own message is on stderr, ours names the file
                reason = (f"ffmpeg stopped taking frames after {self.written}{_space_hint(self.path)}: "
                          f"{str(exc).splitlines()[0]}")
                raise OSError(errno.EPIPE, reason, str(self.path)) from exc
        else:
            # bits=8: quantized to 256 colours now (a steady cost per frame, one byte a pixel kept);
            # the delays are the whole list each time, the last call's is what Pillow uses
            self._writer.write(image, duration=self._durations, loop=0, bits=8)
        self.written += 1

    def commit(self) -> Path:
        """Close, check and rename to the name asked for; on any failure the temporary file is removed."""
        try:
            self._writer.close()  # a GIF is encoded here
            self._writer = None  # kept until closed: discard() must empty a GIF writer that failed
            if self.kind == "video":
                counted = _count_video_frames(self.temporary)
                if counted != self.written:
                    raise OSError(errno.EIO, f"the movie is incomplete: {counted} of {self.written} frames "
                                  f"could be read back{_space_hint(self.path)}", str(self.path))
            os.replace(self.temporary, self.path)
        except OSError as exc:
            self.discard()
            if exc.filename is None and exc.strerror:  # Pillow's write errors name no file: ours is the one
                raise OSError(exc.errno, exc.strerror, str(self.path)) from exc
            raise
        except BaseException:
            self.discard()
            raise
        return self.path

    def discard(self):
        """Stop writing and remove the temporary file (idempotent; never raises an error)."""
        writer, self._writer = getattr(self, "_writer", None), None
        if writer is not None:
            if self.kind == "gif":
                # closing Pillow's writer would encode every frame held, only to delete them
                getattr(writer, "images_to_write", []).clear()
            try:
                writer.close()
            except Exception:  # already failing or cancelled: the file goes anyway
                log.debug("closing the writer of %s failed", self.temporary, exc_info=True)
        try:
            self.temporary.unlink(missing_ok=True)
        except OSError:
            log.warning("could not remove %s", self.temporary, exc_info=True)


def _gif_delays(fps: float, frames: int) -> list:
    # a GIF's delays are whole hundredths of a second: each frame ends at its own time rounded,
    # so the movie keeps the rate asked for on average (30 fps: 30, 40, 30, 30, 40, 30 ms ...)
    ends = np.round(np.arange(1, frames + 1) * 100.0 / fps).astype(int)
    return (10 * np.diff(ends, prepend=0)).tolist()


def _count_video_frames(path: Path) -> int:
    """Frames in a video's first video stream, counted by ffmpeg from the packets (nothing decoded)."""
    import imageio_ffmpeg

    done = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-nostdin", "-v", "error", "-stats",
                           "-i", str(path), "-map", "0:v:0", "-c", "copy", "-f", "null", "-"],
                          capture_output=True, text=True, errors="replace", timeout=600)
    counts = [line.split("frame=", 1)[1].split()[0] for line in done.stderr.replace("\r", "\n").splitlines()
              if line.startswith("frame=")]
    if done.returncode != 0 or not counts or not counts[-1].isdigit():
        return 0
    return int(counts[-1])


def _space_hint(path: Path) -> str:
    # ffmpeg's reason goes to its own stderr; a full disk is the usual one, and easy to check
    try:
        free = shutil.disk_usage(path.parent).free
    except OSError:
        return ""
    return f" (the disk has {free / 1e6:.1f} MB free)" if free < 50e6 else ""


# -- the export ------------------------------------------------------------------------------------


class MovieExport:
    """A movie of a recording being made, one frame per :meth:`step`, then :meth:`finish`.

    Everything is checked and the temporary file created on construction (nothing is rendered
    yet). Use it on one thread (the renderer's); :func:`write_movie` is the loop.

    Parameters
    ----------
    recording : Recording
    solver : solver.Reconstructor
        Built for ``recording.grid`` (:meth:`ViewerModel.build`); it may be shared, the window's
        model's own included (solving on the model's worker thread meanwhile): a solver may be
        shared between threads (see :mod:`tactile_viewer.model.series_solving`).
    path : str or Path
        The movie: ``.mp4``, ``.mkv``, ``.avi`` or ``.gif``. An existing file of that name is replaced
        once the movie is complete.
    start, stop : int
        Frames ``start .. stop - 1`` (``stop`` exclusive; None: to the end).
    fps : float
        Frames per second of the movie.
    size : (2,) tuple of int
        Width and height, pixels (even for a video).
    display : Display, optional
        What the scene shows, as given; default
        :func:`~tactile_viewer.model.movie_settings.default_display` (fixed colour ranges) seen
        from ``camera`` when it is a preset, from ``"iso"`` otherwise.
    shear_ratio, shear_direction : float or None
        Fixed parameters (ratio, radians), both given; both None (default): found for each frame.
    camera : {"iso", "top"} or vtkCamera
        A preset, or a camera copied whole (see :class:`~tactile_viewer.render.frame_renderer.FrameRenderer`).
    smooth : bool
        Anti-aliasing (about three times the render time under software rendering).

    Attributes
    ----------
    frames : range
        The recording's frames the movie shows.
    done : int
        Frames written so far.
    """

    def __init__(self, recording: Recording, solver, path, *, start=0, stop=None, fps=DEFAULT_FPS,
                 size=DEFAULT_SIZE, display: Display | None = None, shear_ratio=None, shear_direction=None,
                 camera="iso", smooth: bool = True):
        path = Path(path)
        kind = movie_kind(path)
        if solver.grid.key != recording.grid.key:
            raise ValueError("solver was built for another geometry than the recording's")
        self.frames = check_frames(len(recording), start, stop)
        self.fps = check_fps(fps, kind)
        self.size = check_size(size, kind)
        if kind == "gif" and len(self.frames) * self.size[0] * self.size[1] > GIF_MAX_BYTES:
            width, height = self.size
            raise ValueError(f"a GIF holds its frames in memory until it is written: {len(self.frames)} "
                             f"frames of {width} x {height} need more than {GIF_MAX_BYTES >> 20} MiB; "
                             "make a video (.mp4) or a shorter or smaller GIF")
        if display is not None and not isinstance(display, Display):
            raise ValueError(f"display must be a Display, got {shown(display)}")
        self.shear_ratio, self.shear_direction = check_movie_parameters(shear_ratio, shear_direction)
        camera = check_camera(camera)
        self.recording, self.solver, self.path = recording, solver, path
        if display is None:
            display = default_display(recording, solver, camera=camera if isinstance(camera, str) else "iso")
        self.display = display
        self.done = 0
        self._seconds = []
        self._file = _MovieFile(path, kind=kind, fps=self.fps, frames=len(self.frames))
        try:
            self._renderer = FrameRenderer(recording.grid, size=self.size, camera=camera, smooth=smooth)
        except BaseException:
            self._file.discard()
            raise

    @property
    def total(self) -> int:
        """Frames the movie will have."""
        return len(self.frames)

    @property
    def remaining(self) -> int:
        """Frames still to be written."""
        return self.total - self.done

    def solve(self, index: int) -> Solved:
        """Frame ``index`` of the recording solved with the movie's parameters."""
        stress = np.asarray(self.recording.frames[index], dtype=float)
        start = time.perf_counter()
        if self.shear_ratio is None:
            result = self.solver.solve(stress)
        else:
            result = self.solver.solve(stress, shear_ratio=self.shear_ratio,
                                       shear_direction=self.shear_direction)
        return Solved.of(self.recording.grid, stress, result, frame=index,
                         time=float(self.recording.t[index]), solve_ms=1e3 * (time.perf_counter() - start),
                         auto=self.shear_ratio is None)

    def step(self):
        """Solve, render and write the next frame. A failure removes the temporary file and is raised."""
        if self.remaining <= 0:
            raise RuntimeError("every frame has been written: finish() is next")
        start = time.perf_counter()
        try:
            solved = self.solve(self.frames[self.done])
            self._file.append(self._renderer.render(solved, self.display))
        except BaseException:
            self.cancel()
            raise
        self._seconds.append(time.perf_counter() - start)
        self.done += 1

    def finish(self) -> MovieResult:
        """Close the movie and give it its name (after every frame has been written)."""
        if self.remaining:
            self.cancel()
            raise RuntimeError(f"finish() after {self.done} of {self.total} frames")
        self._renderer.close()
        start = time.perf_counter()
        self._file.commit()  # removes the temporary file when it fails
        return MovieResult(self.path, self.done, self.size, self.fps, np.array(self._seconds),
                           time.perf_counter() - start)

    def cancel(self):
        """Stop: the temporary file is removed and the renderer released (idempotent)."""
        self._renderer.close()
        self._file.discard()


def write_movie(recording: Recording, path, *, solver=None, kernel: str | None = None, configuration=None,
                progress=None, **options) -> MovieResult:
    """Write a movie of ``recording``'s frames (see :class:`MovieExport` for ``options``).

    Parameters
    ----------
    recording : Recording
    path : str or Path
        ``.mp4``, ``.mkv``, ``.avi`` (H.264) or ``.gif``.
    solver : optional
        A solver built for the recording's geometry; default: built here once
        (:meth:`ViewerModel.build` with ``kernel`` and ``configuration``).
    kernel : str, optional
        The kernel of the solver built here (default the solver's default).
    configuration : solver.quality.Configuration, optional
        A quality preset for the solver built here.
    progress : callable, optional
        ``progress(done, total) -> bool`` after each frame; False cancels (:class:`Cancelled` is raised,
        nothing is left under ``path`` nor beside it).
    **options
        ``start``, ``stop`` (exclusive), ``fps``, ``size``, ``display``, ``shear_ratio``,
        ``shear_direction`` (radians), ``camera``, ``smooth``.

    Returns
    -------
    MovieResult

    Raises
    ------
    ValueError
        A bad argument (named), before anything is written.
    OSError
        The folder is missing or cannot be written, the disk filled, ffmpeg failed; nothing is left.
    Cancelled
        ``progress`` returned False.
    """
    movie_kind(path)  # the name is checked before a solver is built
    if solver is None:
        from solver.kernels import KERNELS

        solver = ViewerModel.build(recording.grid, kernel or KERNELS[0], configuration)
    export = MovieExport(recording, solver, path, **options)
    try:
        while export.remaining:
            export.step()
            if progress is not None and progress(export.done, export.total) is False:
                raise Cancelled(f"cancelled after {export.done} of {export.total} frames")
        return export.finish()
    except BaseException:
        export.cancel()
        raise
