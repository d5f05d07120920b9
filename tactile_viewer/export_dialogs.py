"""Exports from the window: a screenshot with its sidecar, the forces of a frame or of a whole recording.

The file formats are :mod:`tactile_viewer.export`'s; here are the dialogs and
the checks that keep a bad folder from ending the app. Whole-recording
exports run as a task behind a progress dialog.
"""

from __future__ import annotations

import os
from pathlib import Path

from PyQt6 import QtWidgets

from . import export
from .model import ViewerModel
from .scene import Scene
from .tasks import TaskRunner

__all__ = ["ExportActions"]


class ExportActions:
    """The File menu's exports for one window.

    Parameters
    ----------
    parent : QWidget
        The window the dialogs belong to.
    model, scene, tasks
        What is shown, what draws it, where slow work runs.
    error, notify : callable
        ``error(title, text)`` shows an error; ``notify(text)`` a passing note.
    """

    def __init__(self, parent: QtWidgets.QWidget, model: ViewerModel, scene: Scene, tasks: TaskRunner, *,
                 error, notify):
        self.parent, self.model, self.scene, self.tasks = parent, model, scene, tasks
        self._error, self._notify = error, notify

    def add_actions(self, menu: QtWidgets.QMenu) -> list:
        """The export entries of the File menu; returned so the window can enable them."""
        return [
            menu.addAction("Export &screenshot...", self.screenshot_dialog),
            menu.addAction("Export forces of this &frame...", lambda: self.forces_dialog(whole=False)),
            menu.addAction("Export forces of the whole &recording...",
                           lambda: self.forces_dialog(whole=True)),
        ]

    def screenshot_dialog(self):
        dialog = QtWidgets.QDialog(self.parent)
        dialog.setWindowTitle("Export screenshot")
        form = QtWidgets.QFormLayout(dialog)
        scale = QtWidgets.QComboBox()
        scale.addItems(["1x", "2x", "4x"])
        transparent = QtWidgets.QCheckBox("transparent background")
        form.addRow("size", scale)
        form.addRow(transparent)
        buttons = QtWidgets.QDialogButtonBox(QtWidgets.QDialogButtonBox.StandardButton.Ok
                                             | QtWidgets.QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(dialog.accept)
        buttons.rejected.connect(dialog.reject)
        form.addRow(buttons)
        if dialog.exec() != QtWidgets.QDialog.DialogCode.Accepted:
            return
        path, _ = QtWidgets.QFileDialog.getSaveFileName(self.parent, "Save screenshot", "screenshot.png",
                                                        "PNG (*.png)")
        if path:
            try:
                self.export_screenshot(path, scale=int(scale.currentText()[0]),
                                       transparent=transparent.isChecked())
            except (OSError, ValueError) as exc:
                self._error("Cannot save screenshot", f"{path}: {getattr(exc, 'strerror', None) or exc}")

    def export_screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> Path:
        """Save the scene as PNG plus a JSON sidecar naming the recording, frame and parameters."""
        path = Path(path).with_suffix(".png")
        if self.model.last is None:
            # the sidecar names the frame and parameters shown: there must be one
            raise ValueError("no frame has been reconstructed yet")
        # VTK would only print a warning and write nothing
        if not path.parent.is_dir():
            raise FileNotFoundError(2, "the folder does not exist", str(path.parent))
        if not os.access(path.parent, os.W_OK):
            raise PermissionError(13, "the folder cannot be written", str(path.parent))
        self.scene.screenshot(path, scale=scale, transparent=transparent)
        export.write_sidecar(path, **self.model.describe(), scale=scale, transparent=transparent)
        self._notify(f"saved {path}")
        return path

    def forces_dialog(self, *, whole: bool):
        path, _ = QtWidgets.QFileDialog.getSaveFileName(
            self.parent, "Export forces", "forces.npz", "NumPy archive (*.npz);;CSV (*.csv)")
        if path:
            self.export_forces(path, whole=whole)

    def export_forces(self, path, *, whole: bool):
        """Write reconstructed forces of the frame on screen or of all frames (in a task, with progress).

        The frame on screen is written as it was solved (a live frame too); the whole recording
        is solved again frame by frame with the current parameters.
        """
        model = self.model
        source = model.source.label if model.source is not None else ""
        if not whole:
            last = model.last
            if last is None:
                self._error("Nothing to export", "no frame has been reconstructed yet")
                return

            def work(progress):
                table = export.force_table([last.result], [last.frame], [last.time], model.grid,
                                           solver=model.reconstructor, source=source,
                                           mode="auto" if last.auto else "manual")
                return export.save_forces(table, path, source=source)
        else:
            recording, reconstructor = model.recording, model.reconstructor
            if recording is None:
                self._error("Nothing to export", "a live source has no whole recording: record it first")
                return
            given = {} if model.auto else dict(shear_ratio=model.shear_ratio,
                                               shear_direction=model.shear_direction)

            def work(progress):
                table = export.reconstruct_frames(recording, reconstructor, None, progress=progress, **given)
                return export.save_forces(table, path, source=source)

        self.tasks.run(work, lambda written: self._notify(f"saved {written}"), "Exporting forces...",
                       determinate=True)
