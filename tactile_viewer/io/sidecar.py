"""Screenshot sidecars, and the name any export is written under. No Qt.

Screenshot sidecar: ``<image name>.view.json`` beside the image, the image's
full name kept (``board.png`` -> ``board.png.view.json``), so it never takes the
name of another file of the same stem (``board.json``). It is a JSON object
whose ``tactile_viewer_sidecar`` key (the format's version, 1) marks it as ours;
then what the image shows (recording, frame, parameters, display). An existing
file of the sidecar's name is replaced only when it carries that key: anything
else is left as it is and :class:`SidecarConflict` names it.
"""

from __future__ import annotations

import errno
import json
import math
import os
from pathlib import Path

__all__ = ["SIDECAR_SUFFIX", "SIDECAR_MARKER", "SIDECAR_VERSION", "SidecarConflict", "sidecar_path",
           "check_sidecar", "write_sidecar", "derived_name"]

SIDECAR_SUFFIX = ".view.json"  # appended to the image's full name
SIDECAR_MARKER = "tactile_viewer_sidecar"  # the key that marks a sidecar as ours; its value is the version
SIDECAR_VERSION = 1
_SIDECAR_MAX_BYTES = 1 << 20  # a sidecar is about 1 kB: a larger file is not one of ours


def derived_name(picked, suffix: str, *, what: str = "file") -> Path:
    """The name an export is written under: the name picked, ending in ``suffix``.

    A name already ending in ``suffix`` (in any case) keeps it, in lower case;
    another gets ``suffix`` added (``shot`` -> ``shot.png``, ``a.b`` -> ``a.b.png``).
    A name so made is not the one the save dialog asked about replacing, so
    it must be free.

    Parameters
    ----------
    picked : str or Path
        The name picked in the save dialog.
    suffix : str
        The ending, with its dot, in lower case (``".png"``).
    what : str
        What is written, for the error ("image", "movie").

    Raises
    ------
    FileExistsError
        When the name made differs from ``picked`` and a file has it; nothing
        is written.
    """
    picked = Path(picked)
    if picked.suffix.lower() == suffix:
        path = picked.with_suffix(suffix)
    else:
        path = picked.with_name(picked.name + suffix)
    if path != picked and os.path.lexists(path):
        found = (f"not replaced: the {what} would be {path.name} (the name picked, ending in {suffix!r}), "
                 "which exists and is not the file picked")
        raise FileExistsError(errno.EEXIST, found, str(path))
    return path


class SidecarConflict(ValueError):
    """A screenshot's sidecar name is taken by a file that is not one of our sidecars.

    Nothing was written to that file. A :class:`ValueError`, so the command line
    reports it as it reports bad input.

    Attributes
    ----------
    path : Path
        The sidecar's name, the file that was left alone.
    image : Path
        The screenshot the sidecar belongs to.
    """

    def __init__(self, path, image, found: str):
        self.path, self.image = Path(path), Path(image)
        super().__init__(f"{self.path}: the sidecar of {self.image.name} was not written: a sidecar replaces "
                         f"only an earlier sidecar (a JSON object with the key {SIDECAR_MARKER!r}), "
                         f"and this file {found}")


def sidecar_path(image_path) -> Path:
    """The name of a screenshot's sidecar: the image's full name plus ``.view.json``.

    Parameters
    ----------
    image_path : str or Path
        The screenshot, e.g. ``board.png``.

    Returns
    -------
    Path
        ``board.png.view.json`` beside it.
    """
    image = Path(image_path)
    return image.with_name(image.name + SIDECAR_SUFFIX)


def check_sidecar(image_path) -> Path:
    """The sidecar's name for ``image_path``, checked free: absent, or one of our sidecars.

    Writes nothing; callers may use it to refuse before doing any work.

    Returns
    -------
    Path
        :func:`sidecar_path` of ``image_path``.

    Raises
    ------
    SidecarConflict
        When a file of that name exists and is not one of our sidecars (not JSON,
        not an object, without :data:`SIDECAR_MARKER`, a folder, unreadable).
    """
    path = sidecar_path(image_path)
    found = _foreign(path)
    if found:
        raise SidecarConflict(path, image_path, found)
    return path


def _foreign(path: Path) -> str:
    """What makes ``path`` something other than one of our sidecars ("" when absent or ours)."""
    if not os.path.lexists(path):
        return ""
    if path.is_dir():
        return "is a folder"
    if not path.exists():
        return "is a link to nothing"
    try:
        size = path.stat().st_size
        if size > _SIDECAR_MAX_BYTES:
            return f"has {size} bytes, more than any sidecar"
        info = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    except ValueError:  # JSONDecodeError and UnicodeDecodeError alike
        return "is not JSON"
    if not isinstance(info, dict):
        return f"is a JSON {type(info).__name__}, not an object"
    if SIDECAR_MARKER not in info:
        return "is JSON without that key"
    return ""


def write_sidecar(image_path, **info) -> Path:
    """Write the sidecar ``<image name>.view.json`` next to a screenshot, naming what it shows.

    The file starts with the marker ``tactile_viewer_sidecar: 1``; non-finite
    floats are written as null. It replaces an earlier sidecar of ours and
    nothing else.

    Parameters
    ----------
    image_path : str or Path
        The screenshot the sidecar describes (the image itself is not touched).
    **info
        What the image shows, as JSON values (others are written as strings).

    Returns
    -------
    Path
        The sidecar written, :func:`sidecar_path` of ``image_path``.

    Raises
    ------
    SidecarConflict
        When the sidecar's name is taken by a file that is not one of our sidecars;
        that file is left as it was.
    TypeError
        When ``info`` has the marker key itself.
    """
    if SIDECAR_MARKER in info:
        raise TypeError(f"{SIDECAR_MARKER!r} is written by write_sidecar, not given to it")
    # "x" when there was nothing: a file that appears after the check is not overwritten either
    mode = "w" if os.path.lexists(sidecar_path(image_path)) else "x"
    path = check_sidecar(image_path)
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in info.items()}
    text = json.dumps({SIDECAR_MARKER: SIDECAR_VERSION, **clean}, indent=2, default=str) + "\n"
    try:
        with open(path, mode, encoding="utf-8") as handle:
            handle.write(text)
    except FileExistsError:
        raise SidecarConflict(path, image_path, "appeared while the sidecar was being written") from None
    return path
