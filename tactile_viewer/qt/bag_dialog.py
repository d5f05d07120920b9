"""Opening a ROS 2 bag in the window: its topic and field and the skin's layout file, asked for.

File > Open takes our recordings and ROS 2 bags (:func:`ask_recording_path`: a
bag folder is chosen by its ``metadata.yaml``, or a bare ``.mcap`` or ``.db3``).
:func:`load_asking` opens either: a recording of ours as it is, a bag through
:class:`BagDialog`, which lists the bag's numeric array fields
(:func:`tactile_viewer.io.ros2_bag.array_topics`) and takes the sensor layout
file; the bag opens when OK is pressed, and an error (a layout with another
number of taxels, a field that holds no frames) stays in the dialog to be
corrected. The dialog remembers the last layout, topic and field.
"""

from __future__ import annotations

from pathlib import Path

from PyQt6 import QtCore, QtWidgets

from ..io.bag_topics import chosen_fields
from ..io.files import load
from ..io.layout import LayoutError, load_layout
from ..io.recording import Recording, RecordingError
from ..io.ros2_bag import array_topics, bag_location, is_ros2_bag
from .form_rows import add_buttons, add_message, layout_file_row
from .preferences import Settings, last_folder

__all__ = ["BagDialog", "load_asking", "ask_recording_path", "RECORDING_FILTER", "settings"]

RECORDING_FILTER = "Recordings and ROS 2 bags (*.mcap *.npz *.csv *.db3 metadata.yaml);;All files (*)"


def settings() -> Settings:
    """Where the dialog remembers the last layout, topic and field (``bag.json``)."""
    return Settings("bag")


def ask_recording_path(parent) -> Path | None:
    """File > Open's file dialog: a recording or a bag (its ``metadata.yaml`` stands for its folder)."""
    path, _ = QtWidgets.QFileDialog.getOpenFileName(parent, "Open recording or ROS 2 bag", str(last_folder()),
                                                    RECORDING_FILTER)
    return bag_location(path) if path else None


def load_asking(parent, path, *, layout=None, topic=None, field=None) -> Recording | None:
    """Open ``path``; a ROS 2 bag asks for what is not given or not decided (None: cancelled).

    A bag whose ``layout`` is given opens without a question when ``topic`` and ``field``
    (or the bag, by having only one numeric array field, or one of the layout's size) leave
    one choice.

    Raises
    ------
    RecordingError
        What :func:`tactile_viewer.io.files.load` raises, or the bag cannot be read or holds
        no numeric array.
    """
    if not is_ros2_bag(path):
        return load(path, layout=layout, topic=topic, field=field)
    fields = array_topics(path)
    if layout is not None:
        try:
            taxels = load_layout(layout).count
        except LayoutError as exc:  # it names the file
            raise RecordingError(f"sensor layout {exc}") from None
        left = chosen_fields(fields, topic=topic, field=field, taxels=taxels)
        if len(left) == 1:
            return load(path, layout=layout, topic=left[0].topic, field=left[0].field)
    dialog = BagDialog(path, fields, layout=layout, topic=topic, field=field, parent=parent)
    if dialog.exec() == QtWidgets.QDialog.DialogCode.Accepted:
        return dialog.recording
    return None


class BagDialog(QtWidgets.QDialog):
    """Choose a ROS 2 bag's topic and field and the skin's sensor layout; OK opens the bag.

    Parameters
    ----------
    path : Path
        The bag.
    fields : list of ArrayField
        Its numeric array fields (:func:`tactile_viewer.io.ros2_bag.array_topics`).
    layout : str or Path, optional
        The layout file shown first (default: the last one used).
    topic, field : str, optional
        The field shown first (default: the last one used, when the bag has it).

    Attributes
    ----------
    recording : Recording or None
        The bag opened, once OK succeeded.
    """

    def __init__(self, path, fields, *, layout=None, topic=None, field=None, parent=None):
        super().__init__(parent)
        self.path = Path(path)
        self.fields = list(fields)
        self.recording: Recording | None = None
        self.setWindowTitle(f"Open ROS 2 bag {self.path.name}")
        self.setMinimumWidth(620)
        form = QtWidgets.QFormLayout(self)
        name = QtWidgets.QLabel(self.path.name)
        name.setToolTip(str(self.path))
        form.addRow("bag", name)
        self.field_box = QtWidgets.QComboBox()
        for each in self.fields:
            self.field_box.addItem(each.label())
        self.field_box.setToolTip("The topic and the field of its messages that hold one frame each: its "
                                  "values are the raw values of every taxel, in the layout's order")
        form.addRow("topic and field", self.field_box)
        self.layout_edit = QtWidgets.QLineEdit()
        self.layout_edit.setToolTip("The skin's sensor layout file (JSON: grid or positions, pitch, "
                                    "elastomer thickness, Poisson ratio, and the units, gain and offset of "
                                    "the values), the one a live board of this skin uses")
        form.addRow("sensor layout", layout_file_row(self, self.layout_edit))
        self.message = add_message(form)
        self.buttons = add_buttons(form, self._accept, self.reject,
                                   accept_button=QtWidgets.QDialogButtonBox.StandardButton.Open)
        remembered = settings()

        def text(key, given):  # what was given, else what was remembered (an edited file's number: none)
            value = given if given is not None else remembered.value(key)
            return str(value) if isinstance(value, (str, Path)) else None
        self.layout_edit.setText(text("layout", layout) or "")
        if topic is None and field is None:  # what was given is shown, else the last choice
            topic, field = text("topic", None), text("field", None)
        self._select(topic, field)

    def _select(self, topic, field):
        # the first field that matches what was given or remembered; else the one with the most
        # values per message (a skin's array is longer than a robot's joint or IMU arrays)
        matching = [i for i, each in enumerate(self.fields)
                    if (topic is None or each.topic == topic) and (field is None or each.field == field)]
        if matching and (topic, field) != (None, None):
            self.field_box.setCurrentIndex(matching[0])
        elif self.fields:
            longest = max(range(len(self.fields)), key=lambda i: self.fields[i].values or 0)
            self.field_box.setCurrentIndex(longest)


    def choice(self) -> dict:
        """``layout``, ``topic``, ``field`` as :func:`tactile_viewer.io.files.load` takes them.

        Raises
        ------
        ValueError
            No field to choose, or no layout file named.
        """
        if self.field_box.currentIndex() < 0:
            raise ValueError("the bag holds no topic of numeric arrays")
        layout = self.layout_edit.text().strip()
        if not layout:
            raise ValueError("choose the sensor layout file (JSON) of the skin the bag recorded")
        chosen = self.fields[self.field_box.currentIndex()]
        return dict(layout=layout, topic=chosen.topic, field=chosen.field)

    def _accept(self):
        # the bag opens here, so that a wrong layout or field is said where it can be changed
        try:
            choice = self.choice()
            QtWidgets.QApplication.setOverrideCursor(QtCore.Qt.CursorShape.WaitCursor)
            try:
                self.recording = load(self.path, **choice)
            finally:
                QtWidgets.QApplication.restoreOverrideCursor()
        except (RecordingError, ValueError) as exc:
            self.message.setText(str(exc))
            return
        settings().update(choice)
        self.accept()
