"""The Help menu's texts: the quick help (controls, keys, what the numbers mean) and the About box."""

from __future__ import annotations

from PyQt6 import QtCore, QtWidgets

__all__ = ["HELP_HTML", "about_text"]


HELP_HTML = """
<h3>Reading the picture</h3>
<p>Each arrow is the force on one node of the skin's surface, its tip on the surface, pointing where
the force pushes; its colour is its size (left colour bar, mN). The red arrow is a contact's resultant
at its centre. The map is the reconstructed normal pressure (or the measured sensor stress).
Directions are angles from +x (0 deg = +x, 90 deg = +y).</p>
<h3>The two parameters</h3>
<p><b>Auto</b> picks, per contact, the shear ratio and direction whose compressive load explains the
sensors best (the efficiency maximum). Moving a slider switches Auto off and solves with your values.</p>
<p>Torsion is invisible to a normal-stress skin: a twist (shear circling a centre) changes no
sensor reading, so no torque is ever shown; a twisting contact appears as if it did not twist
(its normal load, and any one-way shear). See docs/torsion.md.</p>
<h3>Mouse</h3>
<p>Left drag: rotate. Shift + left drag or middle drag: pan. Wheel or right drag: zoom.
Point at a taxel to read its values.</p>
<h3>Keys</h3>
<table>
<tr><td>Space</td><td>play / pause</td></tr>
<tr><td>Left, Right</td><td>one frame back, on</td></tr>
<tr><td>Home, End</td><td>first, last frame</td></tr>
<tr><td>A</td><td>Auto on / off</td></tr>
<tr><td>Ctrl+O</td><td>open a recording (or drop one on the window)</td></tr>
</table>
<h3>Files</h3>
<p>Recordings: .mcap (live recordings, raw values and calibration), .npz and .csv.
Frames are numbered from 0 everywhere: window, exports, sidecars, --frame and --report.</p>
"""


def about_text() -> str:
    """The About box: version, the libraries and where the log is written."""
    import platform
    from importlib import metadata

    import numpy
    import pyvista
    import scipy

    def version(name):
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "?"

    reporter = getattr(QtWidgets.QApplication.instance(), "reporter", None)
    log_path = getattr(reporter, "log_path", None)
    return (f"<b>tactile-viewer {version('tactile-viewer')}</b><br>"
            "Contact forces on a robot skin from its normal-stress sensors.<br><br>"
            f"Python {platform.python_version()}, numpy {numpy.__version__}, scipy {scipy.__version__}, "
            f"pyvista {pyvista.__version__}, Qt {QtCore.qVersion()}, PyQt {QtCore.PYQT_VERSION_STR}<br>"
            f"Log: {log_path if log_path else 'standard error only'}")
