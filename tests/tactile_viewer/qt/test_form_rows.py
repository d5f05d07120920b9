"""The dialogs' shared rows (tactile_viewer/qt/form_rows.py): the layout file's Browse button, OK and Cancel."""

from PyQt6 import QtWidgets

from tactile_viewer.qt.form_rows import add_buttons, add_message, layout_file_row


def test_browse_puts_the_picked_layout_in_the_field_and_a_cancel_leaves_it(qtbot, monkeypatch):
    dialog = QtWidgets.QDialog()
    qtbot.addWidget(dialog)
    edit, chosen, answers = QtWidgets.QLineEdit("old.json"), [], ["/lab/skin.json", ""]
    asked = []

    def pick(parent, title, start, kinds):
        asked.append((parent, title, start, kinds))
        return answers.pop(0), ""
    monkeypatch.setattr(QtWidgets.QFileDialog, "getOpenFileName", staticmethod(pick))
    row = layout_file_row(dialog, edit, chosen=lambda: chosen.append(edit.text()))
    button = row.itemAt(1).widget()
    assert row.itemAt(0).widget() is edit and button.text() == "Browse..."
    button.click()
    assert edit.text() == "/lab/skin.json" and chosen == ["/lab/skin.json"]
    assert asked[0] == (dialog, "Sensor layout", "old.json", "Sensor layout (*.json);;All files (*)")
    button.click()  # cancelled: nothing changes, nothing is called
    assert edit.text() == "/lab/skin.json" and chosen == ["/lab/skin.json"] and asked[1][2] == "/lab/skin.json"


def test_message_and_buttons_under_a_form(qtbot):
    dialog = QtWidgets.QDialog()
    qtbot.addWidget(dialog)
    form = QtWidgets.QFormLayout(dialog)
    message = add_message(form)
    calls = []
    buttons = add_buttons(form, lambda: calls.append("accept"), lambda: calls.append("reject"),
                          accept_button=QtWidgets.QDialogButtonBox.StandardButton.Open)
    assert message.text() == "" and message.wordWrap() and "#b00020" in message.styleSheet()
    assert add_message(form, error=False).styleSheet() == ""
    buttons.button(QtWidgets.QDialogButtonBox.StandardButton.Open).click()
    buttons.button(QtWidgets.QDialogButtonBox.StandardButton.Cancel).click()
    assert calls == ["accept", "reject"] and form.rowCount() == 3
