"""The README's window picture, made by the window's own export (File > Export screenshot, whole window).

Opens the viewer on a recording at 1280x760 (a laptop's 1280x800 screen less its title bar), waits
until the frame is drawn and the time plots have the whole recording, and saves the window as
a PNG with its JSON sidecar::

    xvfb-run -a -s "-screen 0 1280x800x24" python -m tools.window_screenshot docs/window.png \
        [--recording sample_data/two_contacts.npz] [--frame 30]

Settings the window keeps between runs are not read or written (a throw-away settings folder).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the PNG to write (its sidecar goes beside it)")
    parser.add_argument("--recording", type=Path, default=ROOT / "sample_data" / "two_contacts.npz")
    parser.add_argument("--frame", type=int, default=30, help="the frame shown, from 0")
    parser.add_argument("--size", default="1280x760", help="the window's size, WxH")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))

    from PyQt6 import QtCore, QtWidgets

    app = QtWidgets.QApplication.instance() or QtWidgets.QApplication(sys.argv[:1])
    with tempfile.TemporaryDirectory() as settings:
        QtCore.QSettings.setPath(QtCore.QSettings.Format.IniFormat, QtCore.QSettings.Scope.UserScope,
                                 settings)
        from tactile_viewer.qt.main_window import MainWindow

        window = MainWindow()
        window.resize(width, height)
        window.show()
        try:
            if not window.open(args.recording):
                return 2

            def wait(condition, what, seconds=60.0):
                timer = QtCore.QElapsedTimer()
                timer.start()
                while not condition():
                    if timer.elapsed() > seconds * 1e3:
                        raise TimeoutError(f"waited {seconds:g} s for {what}")
                    app.processEvents(QtCore.QEventLoop.ProcessEventsFlag.AllEvents, 50)

            wait(lambda: window.model.last is not None, "the first frame")
            recording = window.model.recording
            window.model.set_frame(args.frame)
            plots = window.time_plots
            wait(lambda: window.model.last.frame == args.frame and not window.model.solving, "the frame")
            wait(lambda: plots.series is not None and len(plots.series.frame) == len(recording),
                 "the time plots")
            wait(lambda: plots.lines_time == plots.cursor_time, "the plots' cursor")
            # a few passes of the event loop: the last repaints reach the screen before the grab
            for _ in range(20):
                app.processEvents(QtCore.QEventLoop.ProcessEventsFlag.AllEvents, 50)
            path = window.exports.export_screenshot(args.out, window=True)
            print(f"saved {path} ({window.width()}x{window.height()}, {args.recording.name} "
                  f"frame {args.frame})")
        finally:
            window.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
