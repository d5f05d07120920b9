"""File > Export for Foxglove: the recording's reconstructed frames as an MCAP file Foxglove shows.

The file and its topics are :mod:`tactile_viewer.io.foxglove_mcap`'s; the solving is
:func:`tactile_viewer.model.foxglove_export.export_foxglove`'s, with the window's solver,
its parameters (Auto, or the sliders' shear ratio and direction) and its arrow scales,
in a task behind a cancellable progress dialog. Frames the solver refuses are left out
and the user is told which; any failure is shown, never raised.
"""

from __future__ import annotations

from pathlib import Path

from PyQt6 import QtWidgets

from ..io import sidecar
from ..model.foxglove_export import FoxgloveExport, export_foxglove
from ..model.viewer_model import ViewerModel
from .tasks import TaskRunner

__all__ = ["FoxgloveExportAction"]

FILTER = "MCAP for Foxglove (*.mcap)"


class FoxgloveExportAction:
    """The File menu's Foxglove export for one window.

    Parameters
    ----------
    parent : QWidget
        The window the dialogs belong to.
    model, tasks
        What is shown (the recording, solver, parameters and display), where slow work runs.
    error, notify : callable
        ``error(title, text)`` shows an error; ``notify(text)`` a passing note.
    """

    def __init__(self, parent: QtWidgets.QWidget, model: ViewerModel, tasks: TaskRunner, *, error, notify):
        self.parent, self.model, self.tasks = parent, model, tasks
        self._error, self._notify = error, notify

    def add_action(self, menu: QtWidgets.QMenu):
        """Add the menu entry; returned so the window can enable it (it needs a whole recording)."""
        action = menu.addAction("Export for F&oxglove (MCAP)...", self.dialog)
        action.setToolTip("The reconstructed frames as an MCAP file Foxglove shows: pressure maps, force "
                          "arrows and per-contact totals (3D and Plot panels)")
        return action

    def dialog(self):
        """Ask for the file, then export."""
        if self.model.recording is None:
            self._error("Nothing to export", "a live source has no whole recording: record it first")
            return
        label = Path(self.model.source.label).stem if self.model.source is not None else "recording"
        picked, _ = QtWidgets.QFileDialog.getSaveFileName(self.parent, "Export for Foxglove",
                                                          f"{label}.foxglove.mcap", FILTER)
        if not picked:
            return
        try:
            path = sidecar.derived_name(picked, ".mcap", what="MCAP file")
        except OSError as exc:
            self._error("Cannot export for Foxglove", f"{picked}: {exc.strerror or exc}")
            return
        self.export(path)

    def export(self, path) -> bool:
        """Solve every frame of the recording shown and write them to ``path`` (``.mcap``), in a task.

        Returns
        -------
        bool
            False when refused (the reason shown); True when started: the task
            runner's ``finished`` brings the :class:`FoxgloveExport` or the error.
        """
        model = self.model
        recording, reconstructor = model.recording, model.reconstructor
        if recording is None:
            self._error("Nothing to export", "a live source has no whole recording: record it first")
            return False
        folder = Path(path).parent
        if not folder.is_dir():
            self._error("Cannot export for Foxglove", f"{path}: the folder does not exist")
            return False
        given = {} if model.auto else dict(shear_ratio=model.shear_ratio,
                                           shear_direction=model.shear_direction)
        display = model.display
        # the window's arrow lengths, so the file reads as the scene does (0 hides them there: the file's own)
        scales = dict(arrow_scale=display.arrow_scale or None,
                      resultant_scale=display.resultant_scale or None)
        source = model.source.label if model.source is not None else ""

        def work(progress):
            return export_foxglove(recording, reconstructor, path, source=source, progress=progress,
                                   **given, **scales)

        self.tasks.run(work, self._done, "Exporting for Foxglove...", determinate=True)
        return True

    def _done(self, written: FoxgloveExport):
        self._notify(f"saved {written.path}: {written.frames} frames, {sum(written.messages.values())} "
                     f"messages on {len(written.messages)} topics")
        if written.refused:
            listed = "\n".join(f"frame {frame}: {reason}" for frame, reason in written.refused[:10])
            more = f"\n... and {len(written.refused) - 10} more" if len(written.refused) > 10 else ""
            self._error("Frames left out of the Foxglove export",
                        f"{written.path} was saved with {written.frames} frames; {len(written.refused)} "
                        f"could not be solved and are not in it:\n{listed}{more}")
