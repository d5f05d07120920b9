"""Recording files: one read for every format and one write, above the formats they dispatch to.

:func:`load` opens a ``.mcap`` (lazily, :mod:`tactile_viewer.io.mcap_reader`),
``.npz`` (:mod:`tactile_viewer.io.npz`) or ``.csv`` recording
(:mod:`tactile_viewer.io.csv_table`) as a
:class:`~tactile_viewer.io.recording.Recording`; every failure is a
:class:`~tactile_viewer.io.recording.RecordingError` that names the file and
what is wrong. :func:`save` writes one as ``.npz`` or ``.csv``. No Qt here.
"""

from __future__ import annotations

import stat
import zipfile
import zlib
from pathlib import Path

from .csv_table import load_csv, save_csv
from .mcap_reader import open_recording
from .npz import load_npz, save_npz
from .recording import SUFFIXES, Recording, RecordingError

__all__ = ["load", "save"]


def load(path) -> Recording:
    """Read a recording (``.mcap``, ``.npz`` or ``.csv``); :class:`RecordingError` names what is wrong.

    An MCAP recording opens lazily (:func:`tactile_viewer.io.mcap_reader.open_recording`).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise RecordingError(f"{path}: unknown recording type {path.suffix!r}, expected one of {SUFFIXES}")
    try:
        # only a regular file: opening a named pipe blocks until something writes to it (File > Open
        # froze the window), and a device never ends
        kind = path.stat().st_mode
        if not stat.S_ISREG(kind):
            what = ("a folder" if stat.S_ISDIR(kind) else "a named pipe (FIFO)" if stat.S_ISFIFO(kind)
                    else "a device" if stat.S_ISCHR(kind) or stat.S_ISBLK(kind) else "a socket"
                    if stat.S_ISSOCK(kind) else "not a regular file")
            raise RecordingError(f"{path}: not a recording file: it is {what}")
        if suffix == ".mcap":
            return open_recording(path)
        if suffix == ".npz":
            return load_npz(path)
        return load_csv(path)
    except RecordingError:
        raise
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except (ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"{path}: {exc}") from exc
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
        # members are decompressed lazily, so a damaged archive can fail long after np.load
        raise RecordingError(f"{path}: damaged NPZ archive ({exc})") from exc


def save(recording: Recording, path) -> Path:
    """Write a recording as ``.npz`` (everything) or ``.csv`` (frames and geometry, nu included)."""
    path = Path(path)
    if path.suffix.lower() == ".npz":
        return save_npz(recording, path)
    if path.suffix.lower() == ".csv":
        return save_csv(recording, path)
    raise RecordingError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
