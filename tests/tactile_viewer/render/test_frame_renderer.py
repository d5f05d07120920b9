"""One movie frame: the caption burnt into it."""

import numpy as np

from tactile_viewer.render.frame_renderer import caption


def test_a_frame_shows_its_own_caption():
    from types import SimpleNamespace

    result = SimpleNamespace(shear_ratio=0.25, shear_direction=np.radians(-120), total_force=np.array([0.3, 0.4, 2.0]))
    text = caption(SimpleNamespace(frame=7, time=0.2333, result=result, auto=False))
    assert text == ("frame 7   t 0.233 s   Fz 2.000 N   Ft 0.500 N\n"
                    "shear ratio 0.25   direction -120 deg   (fixed)")
