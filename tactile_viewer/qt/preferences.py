"""What the window remembers between runs: its place, the recent files, the last folder, the view.

Everything is kept in one JSON file in the user's config folder
(``tactile-viewer/window.json``: ``$XDG_CONFIG_HOME`` or ``~/.config`` on Linux, or
the folder ``TACTILE_VIEWER_CONFIG`` names); the connect dialog keeps its own
(``live.json``). Not Qt's settings files: a 31-byte line in one (a list
declaring 2^31-1 items) made Qt allocate without bound and abort the app at
every start. A file larger than :data:`MAX_SETTINGS_BYTES`, or not JSON, is
ignored as a whole, and a value that cannot be read back (an edited or older
file) one by one, each with a log line: the default is used instead and the
window opens as usual. Writes go to a temporary file renamed over the old one.

The view kept is the part of :class:`~tactile_viewer.model.display.Display` that is
a choice of the user's (the map, the colour map, what is drawn, the
colour-range mode ...), not the scales each new source gets from its own
loads (:data:`PER_SOURCE`), and the playback speed and loop.
"""

from __future__ import annotations

import base64
import binascii
import dataclasses
import gc
import json
import logging
import os
import tempfile
from pathlib import Path

from PyQt6 import QtCore

from ..model.display import Display

log = logging.getLogger(__name__)

__all__ = ["Settings", "window_settings", "saved_window_state", "save_window_state", "RecentFiles",
           "last_folder", "remember_folder", "saved_view", "save_view", "saved_rows", "save_rows",
           "PER_SOURCE", "RECENT_MAX", "MAX_SETTINGS_BYTES"]

RECENT_MAX = 8  # entries of File > Open recent
# Display fields every new source sets from its own loads (model.display.display_scales), and the in-plane
# arrows, which follow the camera (not kept either): not preferences
PER_SOURCE = frozenset({"arrow_scale", "resultant_scale", "threshold", "range_max", "arrow_range_max",
                        "in_plane"})
# what a settings file may weigh: the window's holds a few kilobytes (its docks' state the most)
MAX_SETTINGS_BYTES = 1 << 20


def config_folder() -> Path:
    """Where the settings files are: ``TACTILE_VIEWER_CONFIG``, else the user's config folder."""
    chosen = os.environ.get("TACTILE_VIEWER_CONFIG")
    if chosen:
        return Path(chosen)
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "tactile-viewer"


class Settings:
    """One JSON settings file: ``name -> value`` (text, numbers, true/false, lists of text).

    Read once when made; each :meth:`set_value` or :meth:`remove` writes the
    whole file (a temporary file renamed over the old one: a crash leaves the
    old file or the new, never half of one).

    Parameters
    ----------
    name : str
        The file's stem in :func:`config_folder` (``"window"``, ``"live"``).
    """

    def __init__(self, name: str):
        self.path = config_folder() / f"{name}.json"
        self._values = self._read()

    def _read(self) -> dict:
        try:
            with open(self.path, "rb") as file:
                data = file.read(MAX_SETTINGS_BYTES + 1)
        except FileNotFoundError:
            return {}
        except OSError as exc:
            log.warning("settings: cannot read %s (%s); using the defaults", self.path, exc)
            return {}
        if len(data) > MAX_SETTINGS_BYTES:
            log.warning("settings: ignoring %s: over %d bytes", self.path, MAX_SETTINGS_BYTES)
            return {}
        collecting = gc.isenabled()
        # no garbage collection at the parser's depth: a finalizer run there (a closed plotter's)
        # would hit the recursion limit itself and surface as an error no one can catch
        gc.disable()
        try:
            values = json.loads(data)
        except (ValueError, RecursionError) as exc:  # RecursionError: a deeply nested edit
            log.warning("settings: ignoring %s: not JSON (%s)", self.path, exc)
            return {}
        finally:
            if collecting:
                gc.enable()
        if not isinstance(values, dict):
            log.warning("settings: ignoring %s: not a JSON object", self.path)
            return {}
        return values

    def value(self, name: str, default=None):
        """The value kept under ``name``, or ``default``."""
        return self._values.get(name, default)

    def contains(self, name: str) -> bool:
        return name in self._values

    def set_value(self, name: str, value) -> None:
        """Keep ``value`` (JSON-ready) under ``name`` and write the file."""
        self.update({name: value})

    def update(self, values: dict, *, forget: str | None = None) -> None:
        """Keep every ``name: value`` of ``values``, after forgetting the names that start with
        ``forget`` (a group a newer version may have changed), and write the file once."""
        if forget is not None:
            self._values = {k: v for k, v in self._values.items() if not k.startswith(forget)}
        self._values.update(values)
        self._write()

    def _write(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(prefix=f".{self.path.stem}-", suffix=".json",
                                                 dir=self.path.parent)
            try:
                with os.fdopen(handle, "w", encoding="utf-8") as file:
                    json.dump(self._values, file, indent=1, sort_keys=True)
                os.replace(temporary, self.path)
            except BaseException:
                os.unlink(temporary)
                raise
        except OSError as exc:  # a read-only home: the window goes on, it only forgets
            log.warning("settings: cannot write %s (%s)", self.path, exc)


def window_settings() -> Settings:
    """The window's settings file."""
    return Settings("window")


def saved_window_state(name: str) -> QtCore.QByteArray | None:
    """The window's saved ``"geometry"`` (size and place) or ``"docks"`` (the docks' state); None when
    there is none or it is not what Qt saved (an edited file: logged, and the default is used)."""
    value = window_settings().value(name)
    if value is None:
        return None
    if isinstance(value, str):
        try:
            return QtCore.QByteArray(base64.b64decode(value, validate=True))
        except (binascii.Error, ValueError):
            pass
    log.warning("settings: ignoring %s = %r (not a saved window layout)", name, str(value)[:80])
    return None


def save_window_state(name: str, state: QtCore.QByteArray):
    """Keep the window's ``"geometry"`` or ``"docks"`` for the next run."""
    window_settings().set_value(name, base64.b64encode(bytes(state)).decode("ascii"))


def _strings(value) -> list[str]:
    # a list of text; anything else (an edited file) is no list
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return value
    if value is not None:
        log.warning("settings: ignoring a list that is not a list of text: %r", str(value)[:80])
    return []


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
        window_settings().set_value(self.KEY, [str(p) for p in paths])


TIME_PLOT_ROWS = "time_plots/rows"  # the rows the user chose (a list of row keys)


def saved_rows(known) -> set[str] | None:
    """The time plots' rows chosen last run, those of ``known`` (None: none saved or none known)."""
    rows = {key for key in _strings(window_settings().value(TIME_PLOT_ROWS)) if key in known}
    return rows or None


def save_rows(rows) -> None:
    """Keep the time plots' rows for the next run."""
    window_settings().set_value(TIME_PLOT_ROWS, sorted(rows))


def last_folder() -> Path:
    """The folder a recording was last opened from (the current folder the first time or once it is gone)."""
    folder = window_settings().value("last_folder")
    if isinstance(folder, str) and Path(folder).is_dir():
        return Path(folder)
    return Path.cwd()


def remember_folder(path):
    """Remember the folder of ``path`` (a file) for the next open or save dialog."""
    window_settings().set_value("last_folder", str(Path(path).resolve().parent))


def _preference_fields():
    return [f for f in dataclasses.fields(Display) if f.name not in PER_SOURCE]


def save_view(display: Display, *, speed: float, loop: bool):
    """Keep the user's view choices of ``display`` and the playback speed and loop."""
    view = {f"view/{field.name}": getattr(display, field.name) for field in _preference_fields()}
    view.update({"view/playback_speed": float(speed), "view/playback_loop": bool(loop)})
    window_settings().update(view, forget="view/")  # fields a newer version dropped do not linger


def saved_view() -> tuple[dict, dict]:
    """The saved view: ``(display changes, {"speed": ..., "loop": ...})``, each only what was read back.

    A value of the wrong type or that :class:`Display` refuses is left out
    (and logged), so a damaged file never keeps the window from opening.
    """
    store = window_settings()
    changes = {}
    for field in _preference_fields():
        key = f"view/{field.name}"
        if not store.contains(key):
            continue
        value = _typed(store.value(key), type(getattr(Display(), field.name)))
        if value is None:
            log.warning("settings: ignoring view.%s = %r", field.name, store.value(key))
            continue
        try:
            dataclasses.replace(Display(), **{field.name: value})
        except ValueError as exc:
            log.warning("settings: ignoring view.%s: %s", field.name, exc)
            continue
        changes[field.name] = value
    playback = {}
    speed = _typed(store.value("view/playback_speed"), float)
    if speed is not None:
        playback["speed"] = speed
    loop = _typed(store.value("view/playback_loop"), bool)
    if loop is not None:
        playback["loop"] = loop
    return changes, playback


def _typed(value, kind):
    # ``value`` as read from JSON if it is a ``kind`` (a whole number counts as a float), else None
    if isinstance(value, bool):
        return value if kind is bool else None
    if kind is float and isinstance(value, (int, float)):
        return float(value)
    if kind in (int, str) and isinstance(value, kind):
        return value
    return None
