"""One movie frame: the app's scene drawn off screen with its caption burnt in. No Qt.

:class:`FrameRenderer` owns an off-screen pyvista plotter with the window's own
:class:`~tactile_viewer.render.scene.Scene` on it; :func:`caption` is the text
burnt into every frame: the frame number and time, the shear ratio and
direction solved with (and whether they were found automatically or given),
and the total normal and tangential force. The scene's actors and the caption
are made once and updated in place, so every frame costs the same.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.display import Display
from ..model.movie_settings import DEFAULT_SIZE, check_camera, check_size
from ..model.solved import Solved

__all__ = ["FrameRenderer", "caption"]


def caption(solved: Solved) -> str:
    """The text burnt into a frame: frame, time, forces, and the parameters solved with.

    Examples
    --------
    >>> from types import SimpleNamespace as S
    >>> r = S(shear_ratio=0.31, shear_direction=math.radians(45), total_force=np.array([0.3, 0.1, 1.0]))
    >>> print(caption(S(frame=12, time=0.4, result=r, auto=True)))
    frame 12   t 0.400 s   Fz 1.000 N   Ft 0.316 N
    shear ratio 0.31   direction +45 deg   (found automatically)
    """
    result = solved.result
    fx, fy, fz = result.total_force
    how = "found automatically" if solved.auto else "fixed"
    direction = math.degrees(result.shear_direction)
    return (f"frame {solved.frame}   t {solved.time:.3f} s   Fz {fz:.3f} N   Ft {math.hypot(fx, fy):.3f} N\n"
            f"shear ratio {result.shear_ratio:.2f}   direction {direction:+.0f} deg   ({how})")


class FrameRenderer:
    """The app's :class:`~tactile_viewer.render.scene.Scene` on its own off-screen plotter, with a caption.

    Must be used (and closed) on one thread: the one that made it.

    Parameters
    ----------
    grid : SensorGrid
    size : (2,) tuple of int
        Width and height of the images, pixels.
    camera : {"iso", "top"} or vtkCamera
        A preset, or a camera copied whole (``DeepCopy``: position, focal point, up, projection,
        parallel scale, view angle, clipping range), as :meth:`Scene.screenshot` copies it: the
        window's view, a zoomed parallel Top view included. Copied now; later changes to it
        do not reach the movie.
    smooth : bool
        Multisample anti-aliasing, as the command line's screenshots.
    """

    def __init__(self, grid, *, size=DEFAULT_SIZE, camera="iso", smooth: bool = True):
        import pyvista as pv

        from .scene import Scene

        width, height = check_size(size, "image")
        camera = check_camera(camera)
        self.size = (width, height)
        self.plotter = pv.Plotter(off_screen=True, window_size=[width, height])
        try:
            self.scene = Scene(self.plotter, smooth=smooth)
            self.scene.set_grid(grid)
            if isinstance(camera, str):
                self.scene.camera(camera)
            else:
                own = self.plotter.renderer.camera  # pyvista's, already marked set by set_grid's preset
                own.DeepCopy(camera)
                # pyvista keeps its own note of the projection: through it, both agree
                own.parallel_projection = bool(camera.GetParallelProjection())
            # one text actor, its text replaced each frame (adding one per frame would grow the cost),
            # centred at the top between the colour bars: its size follows the image so that the
            # longest caption line (about 60 characters) stays inside the middle 70% (the bars are outside)
            font = max(8, min(round(width / 52), round(height / 32)))  # pixels
            self._text = self.plotter.add_text("", position=(width / 2, height - font // 2), color="black",
                                               name="caption")
            self._text.prop.font_size = font  # add_text would double the size it is given
            self._text.prop.justification_horizontal = "center"
            self._text.prop.justification_vertical = "top"
        except BaseException:
            self.plotter.close()
            raise

    def render(self, solved: Solved, display: Display) -> np.ndarray:
        """Draw one frame and return its image, ``(height, width, 3)`` uint8."""
        self.scene.update(solved, display, render=False)
        self._text.input = caption(solved)
        self.plotter.render()
        image = np.asarray(self.plotter.screenshot(None, return_img=True))
        if image.shape[:2] != (self.size[1], self.size[0]):
            # never expected: a render window smaller than asked (a screen limit) would make a movie
            # whose frames do not match the size the writer was opened with
            raise RuntimeError(f"the renderer made {image.shape[1]} x {image.shape[0]} images, "
                               f"not {self.size[0]} x {self.size[1]}")
        return image[..., :3]

    def close(self):
        """Release the plotter (idempotent)."""
        self.plotter.close()
