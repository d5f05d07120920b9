"""The contacts of the frame shown, one row each: its resultant, its own parameters, where it is.

A frame with several contacts is solved with a shear ratio and direction per
contact (``solver.Reconstruction.contacts``); the scene draws a resultant per
contact and this table lists them, largest normal force first, each with its
identity: the number it keeps from frame to frame while it persists (the model
follows the contacts, :class:`solver.ContactTracker`), as in the status line.
"""

from __future__ import annotations

import math

from PyQt6 import QtCore, QtWidgets

from ..model.solved import Solved
from ..model.viewer_model import ViewerModel

__all__ = ["ContactsPanel", "contact_rows", "COLUMNS"]

COLUMNS = ("#", "Fz mN", "Ft mN", "mu", "dir °", "x mm", "y mm", "note")
TIPS = ("Contact number: it keeps it from frame to frame while the contact persists; a new contact gets "
        "the next number, one lost for long is ended (its number never comes back); after a jump in the "
        "recording the numbers start again from 1. The rows are largest normal force first",
        "Normal force of the contact (resultant), millinewtons; positive presses into the skin",
        "Tangential force of the contact, millinewtons",
        "Its shear ratio: tangential over normal force of its template load",
        "Its shear direction, degrees from +x (0 = +x, 90 = +y)",
        "Centre of its compressive load, millimetres", "Centre of its compressive load, millimetres",
        "edge: the contact touches the skin's border, part of its stress field is not sensed, so its "
        "shear is less certain; no shear: Auto found no shear signature on it")


_NUMBERS = QtCore.Qt.AlignmentFlag.AlignRight | QtCore.Qt.AlignmentFlag.AlignVCenter  # the numeric columns


def contact_rows(solved: Solved) -> list[tuple[str, ...]]:
    """The table's rows for ``solved``: one per contact; the whole frame when it has none.

    The first cell is the contact's identity (its place in the list when the
    result was not followed over frames, identity 0). A normal-only solve has
    no contacts: its row is the whole frame's resultant with no parameters.
    """
    result = solved.result
    rows = []
    for number, (contact, centroid) in enumerate(zip(result.contacts, solved.contact_centroids, strict=True),
                                                 start=1):
        notes = []
        if contact.at_edge:
            notes.append("edge")
        if solved.auto and not contact.shear_detected:
            notes.append("no shear")
        rows.append(_row(str(contact.identity or number), contact.total_force, f"{contact.shear_ratio:.2f}",
                         f"{math.degrees(contact.shear_direction):+.0f}", centroid, ", ".join(notes)))
    if not rows and solved.centroid is not None:
        rows.append(_row("all", result.total_force, "-", "-", solved.centroid,
                         "normal only" if result.normal_only else ""))
    return rows


def _row(name, force, ratio, direction, centroid, note) -> tuple[str, ...]:
    x, y = ("-", "-") if centroid is None else (f"{centroid[0] * 1e3:.1f}", f"{centroid[1] * 1e3:.1f}")
    return (name, f"{force[2] * 1e3:.1f}", f"{math.hypot(force[0], force[1]) * 1e3:.1f}", ratio, direction,
            x, y, note)


class ContactsPanel(QtWidgets.QGroupBox):
    """A small table of the contacts of the last solved frame (follows the model's ``solved``)."""

    VISIBLE_ROWS = 3  # at least; the table takes the column's height left (a 1280x800 screen: 3)

    def __init__(self, model: ViewerModel, parent=None):
        super().__init__("Contacts", parent)
        self.model = model
        box = QtWidgets.QVBoxLayout(self)
        self.table = QtWidgets.QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(COLUMNS)
        for column, tip in enumerate(TIPS):
            self.table.horizontalHeaderItem(column).setToolTip(tip)
        self.table.verticalHeader().hide()
        self.table.setEditTriggers(QtWidgets.QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionMode(QtWidgets.QAbstractItemView.SelectionMode.NoSelection)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QtWidgets.QHeaderView.ResizeMode.ResizeToContents)
        # the note takes the width left, however little: the numbers are never scrolled sideways out
        # of view (a stretched last section kept 100 px, 17 px more than a 1280 px window leaves);
        # a note too long for it is elided and whole in its tooltip
        header.setSectionResizeMode(len(COLUMNS) - 1, QtWidgets.QHeaderView.ResizeMode.Stretch)
        self.table.setToolTip("Each contact's resultant and its own shear parameters "
                              "(the red arrows in the scene)")
        row_height = self.table.verticalHeader().defaultSectionSize()
        self.table.setMinimumHeight(self.table.horizontalHeader().sizeHint().height()
                                    + self.VISIBLE_ROWS * row_height + 2 * self.table.frameWidth())
        # its own size hint (a dozen rows) would make the column scroll: it takes what is left
        policy = QtWidgets.QSizePolicy.Policy
        self.table.setSizePolicy(policy.Expanding, policy.Ignored)
        box.addWidget(self.table, 1)
        model.solved.connect(self.follow)
        model.recording_changed.connect(lambda: self.table.setRowCount(0))

    def follow(self, solved: Solved):
        rows = contact_rows(solved)
        self.table.setRowCount(len(rows))  # rows in or out: the view hears of it as usual
        # Every frame changes every cell. Cell by cell, the view and its header (which sizes the
        # columns to their contents) follow each change: 24 times a frame of three contacts, 3 ms of
        # the window's thread. The cells are filled unheard, then the view hears of all at once.
        model = self.table.model()
        blocked = model.blockSignals(True)
        try:
            for r, row in enumerate(rows):
                for c, text in enumerate(row):
                    self._cell(r, c).setText(text)
                self._cell(r, len(COLUMNS) - 1).setToolTip(row[-1])  # the note, whole however narrow
        finally:
            model.blockSignals(blocked)
        if rows:
            model.dataChanged.emit(model.index(0, 0), model.index(len(rows) - 1, len(COLUMNS) - 1), [])

    def _cell(self, r: int, c: int) -> QtWidgets.QTableWidgetItem:
        # the table's item at (r, c), made (numbers right-aligned) the first time the row is used
        item = self.table.item(r, c)
        if item is None:
            item = QtWidgets.QTableWidgetItem()
            if 0 < c < len(COLUMNS) - 1:
                item.setTextAlignment(_NUMBERS)
            self.table.setItem(r, c, item)
        return item
