"""Exports from the window: a screenshot with its sidecar, the forces of a frame or of a whole recording.

The file formats are :mod:`tactile_viewer.export`'s; here are the dialogs and
the checks that keep a bad folder from ending the app. Whole-recording
exports run as a task behind a progress dialog.

Only the file picked in the save dialog (which asks before replacing it) is
replaced. The names the export derives from it -- the ``.png`` ending given to
a name without it, the sidecar ``<image name>.view.json`` -- never replace a file the
user did not pick: the image's is refused, the sidecar's is skipped (the image
kept) and the error names the file left alone.
"""

from __future__ import annotations

import errno
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
            except export.SidecarConflict as exc:  # the image is written: say so, and why the sidecar is not
                self._error("Screenshot saved without its sidecar", f"{exc.image} was saved; {exc}")
            except (OSError, ValueError) as exc:
                self._error("Cannot save screenshot", f"{path}: {getattr(exc, 'strerror', None) or exc}")

    def export_screenshot(self, path, *, scale: int = 1, transparent: bool = False) -> Path:
        """Save the scene as PNG plus its JSON sidecar naming the recording, frame and parameters.

        Parameters
        ----------
        path : str or Path
            The file picked. A name not ending in ``.png`` is given that ending
            (``shot`` -> ``shot.png``, ``shot.PNG`` -> ``shot.png``); that name must then be
            free, since it is not the file picked (nor the one the save dialog asked about).
        scale : int
            The image's size in multiples of the window's.
        transparent : bool
            Whether the background is transparent.

        Returns
        -------
        Path
            The image written; its sidecar is :func:`export.sidecar_path` of it
            (``shot.png.view.json``).

        Raises
        ------
        ValueError
            No frame has been reconstructed yet; nothing is written.
        OSError
            The folder is missing or cannot be written, or the ``.png`` name made from
            the name picked is an existing file (:class:`FileExistsError`); nothing is written.
        export.SidecarConflict
            The sidecar's name is taken by a file that is not one of our sidecars:
            the image has been written, the sidecar has not, that file is untouched.
        """
        picked = Path(path)
        path = _png_name(picked)
        if self.model.last is None:
            # the sidecar names the frame and parameters shown: there must be one
            raise ValueError("no frame has been reconstructed yet")
        # VTK would only print a warning and write nothing
        if not path.parent.is_dir():
            raise FileNotFoundError(2, "the folder does not exist", str(path.parent))
        if not os.access(path.parent, os.W_OK):
            raise PermissionError(13, "the folder cannot be written", str(path.parent))
        if path != picked and os.path.lexists(path):
            found = (f"not replaced: the image would be {path.name} (the name picked, ending in '.png'), "
                     "which exists and is not the file picked")
            raise FileExistsError(errno.EEXIST, found, str(path))
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


def _png_name(picked: Path) -> Path:
    """The name a screenshot is saved as: the name picked, ending in ``.png`` (lower case: pyvista's)."""
    if picked.suffix.lower() == ".png":
        return picked.with_suffix(".png")
    return picked.with_name(picked.name + ".png")
