"""What the window remembers between runs: its place, the recent files, the last folder, the view.

Everything is kept in one INI file in the user's config folder (Qt's
``QSettings``, user scope, ``tactile-viewer/window.ini``); the connect dialog
keeps its own (``live.ini``). A value that cannot be read back (an edited or
older file) is ignored with a log line: the default is used instead and the
window opens as usual.

The view kept is the part of :class:`~tactile_viewer.model.Display` that is
a choice of the user's (the map, the colour map, what is drawn, the
colour-range mode ...), not the scales each new source gets from its own
loads (:data:`PER_SOURCE`), and the playback speed and loop.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

from PyQt6 import QtCore

from .model import Display

log = logging.getLogger(__name__)

__all__ = ["window_settings", "saved_layout", "save_layout", "RecentFiles", "last_folder", "remember_folder",
           "saved_view", "save_view",
           "PER_SOURCE", "RECENT_MAX"]

RECENT_MAX = 8  # entries of File > Open recent
# Display fields every new source sets from its own loads (model._display_scales), and the in-plane
# arrows, which follow the camera (not kept either): not preferences
PER_SOURCE = frozenset({"arrow_scale", "resultant_scale", "threshold", "range_max", "arrow_range_max",
                        "in_plane"})


def window_settings() -> QtCore.QSettings:
    """The window's settings file (an INI file in the user's config folder)."""
    return QtCore.QSettings(QtCore.QSettings.Format.IniFormat, QtCore.QSettings.Scope.UserScope,
                            "tactile-viewer", "window")


def saved_layout(name: str) -> QtCore.QByteArray | None:
    """The window's saved ``"geometry"`` (size and place) or ``"docks"`` (the docks' state); None when
    there is none or it is not what Qt saved (an edited file: logged, and the default is used)."""
    value = window_settings().value(name)
    if value is None:
        return None
    if isinstance(value, (QtCore.QByteArray, bytes)):
        return QtCore.QByteArray(value)
    log.warning("settings: ignoring %s = %r (not a saved window layout)", name, value)
    return None


def save_layout(name: str, state: QtCore.QByteArray):
    """Keep the window's ``"geometry"`` or ``"docks"`` for the next run."""
    window_settings().setValue(name, state)


def _strings(value) -> list[str]:
    # an INI list of one entry reads back as a plain string, of none as None
    if value is None:
        return []
    if isinstance(value, str):
        return [value]
    return [str(v) for v in value]


class RecentFiles:
    """The recordings opened last, newest first, at most :data:`RECENT_MAX`."""

    KEY = "recent_files"

    def paths(self) -> list[Path]:
        return [Path(p) for p in _strings(window_settings().value(self.KEY))]

    def add(self, path) -> list[Path]:
        """Put ``path`` first (once); returns the new list."""
        path = Path(path).resolve()
        paths = [path] + [p for p in self.paths() if p != path]
        self._store(paths[:RECENT_MAX])
        return paths[:RECENT_MAX]

    def remove(self, path) -> list[Path]:
        """Drop ``path`` (a file that is gone); returns the new list."""
        path = Path(path).resolve()
        paths = [p for p in self.paths() if p != path]
        self._store(paths)
        return paths

    def clear(self):
        self._store([])

    def _store(self, paths):
        window_settings().setValue(self.KEY, [str(p) for p in paths])


def last_folder() -> Path:
    """The folder a recording was last opened from (the current folder the first time or once it is gone)."""
    folder = window_settings().value("last_folder")
    if isinstance(folder, str) and Path(folder).is_dir():
        return Path(folder)
    return Path.cwd()


def remember_folder(path):
    """Remember the folder of ``path`` (a file) for the next open or save dialog."""
    window_settings().setValue("last_folder", str(Path(path).resolve().parent))


def _preference_fields():
    return [f for f in dataclasses.fields(Display) if f.name not in PER_SOURCE]


def save_view(display: Display, *, speed: float, loop: bool):
    """Keep the user's view choices of ``display`` and the playback speed and loop."""
    store = window_settings()
    store.beginGroup("view")
    try:
        store.remove("")  # fields a newer version dropped do not linger
        for field in _preference_fields():
            store.setValue(field.name, getattr(display, field.name))
        store.setValue("playback_speed", float(speed))
        store.setValue("playback_loop", bool(loop))
    finally:
        store.endGroup()


def saved_view() -> tuple[dict, dict]:
    """The saved view: ``(display changes, {"speed": ..., "loop": ...})``, each only what was read back.

    A value of the wrong type or that :class:`Display` refuses is left out
    (and logged), so a damaged file never keeps the window from opening.
    """
    store = window_settings()
    store.beginGroup("view")
    try:
        changes = {}
        for field in _preference_fields():
            if not store.contains(field.name):
                continue
            value = _typed(store.value(field.name), type(getattr(Display(), field.name)))
            if value is None:
                log.warning("settings: ignoring view.%s = %r", field.name, store.value(field.name))
                continue
            try:
                dataclasses.replace(Display(), **{field.name: value})
            except ValueError as exc:
                log.warning("settings: ignoring view.%s: %s", field.name, exc)
                continue
            changes[field.name] = value
        playback = {}
        speed = _typed(store.value("playback_speed"), float)
        if speed is not None:
            playback["speed"] = speed
        loop = _typed(store.value("playback_loop"), bool)
        if loop is not None:
            playback["loop"] = loop
        return changes, playback
    finally:
        store.endGroup()


def _typed(value, kind):
    # INI files keep text: "true", "0.25"; None when ``value`` does not read as ``kind``
    if value is None:
        return None
    if kind is bool:
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        return {"true": True, "false": False}.get(text)
    if kind is float:
        try:
            return float(value)
        except (TypeError, ValueError):
            return None
    if kind is int:
        try:
            return int(value)
        except (TypeError, ValueError):
            return None
    if kind is str:
        return value if isinstance(value, str) else None
    return None
