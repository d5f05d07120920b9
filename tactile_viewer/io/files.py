"""Recording files: one read for every format and one write, above the formats they dispatch to.

:func:`load` opens a ``.mcap`` (lazily, :mod:`tactile_viewer.io.mcap_reader`),
``.npz`` (:mod:`tactile_viewer.io.npz`) or ``.csv`` recording
(:mod:`tactile_viewer.io.csv_table`), or a ROS 2 bag with a sensor layout
(:mod:`tactile_viewer.io.ros2_bag`), as a
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
from .foxglove_mcap import is_foxglove_export
from .mcap_reader import open_recording
from .npz import load_npz, save_npz
from .recording import SUFFIXES, Recording, RecordingError
from .ros2_bag import BAG_METADATA, is_ros2_bag, load_ros2_bag

__all__ = ["load", "save", "is_recording_path"]


def load(path, *, layout=None, topic=None, field=None) -> Recording:
    """Read a recording (``.mcap``, ``.npz``, ``.csv``) or a ROS 2 bag; :class:`RecordingError` says why not.

    An MCAP recording opens lazily (:func:`tactile_viewer.io.mcap_reader.open_recording`).
    A ROS 2 bag (a folder with ``metadata.yaml``, a ``.db3``, an ``.mcap`` without this
    viewer's metadata: :func:`~tactile_viewer.io.ros2_bag.is_ros2_bag`) needs ``layout``
    and takes ``topic`` and ``field`` (:func:`~tactile_viewer.io.ros2_bag.load_ros2_bag`);
    a recording of this viewer carries its own layout and takes none of them.
    """
    path = Path(path)
    if path.suffix.lower() == ".mcap" and path.is_file() and _exported_for_foxglove(path):
        raise RecordingError(f"{path}: an export of reconstructed forces for Foxglove (File > Export for "
                             "Foxglove, tactile-batch --format foxglove), not a recording: open it in "
                             "Foxglove, or open the recording it was made from (named in its metadata)")
    if is_ros2_bag(path):
        return load_ros2_bag(path, layout=layout, topic=topic, field=field)
    if (layout, topic, field) != (None, None, None) and path.exists():
        raise RecordingError(f"{path}: not a ROS 2 bag: a layout, topic and field are for bags (a recording "
                             "of this viewer carries its own layout)")
    suffix = path.suffix.lower()
    if path.is_dir() and suffix not in SUFFIXES:
        raise RecordingError(f"{path}: a folder, and no ROS 2 bag (it holds no {BAG_METADATA})")
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


def _exported_for_foxglove(path: Path) -> bool:
    try:
        return is_foxglove_export(path)
    except OSError:  # unreadable: the reader below says why
        return False


def is_recording_path(path) -> bool:
    """Whether :func:`load` takes ``path`` by its name: a recording's suffix, a ``.db3``, a bag folder.

    Nothing is read but the folder (a dropped file is judged as the mouse moves).
    """
    path = Path(path)
    return (path.suffix.lower() in (*SUFFIXES, ".db3") or path.name == BAG_METADATA
            or (path / BAG_METADATA).is_file())


def save(recording: Recording, path) -> Path:
    """Write a recording as ``.npz`` (everything) or ``.csv`` (frames and geometry, nu included)."""
    path = Path(path)
    if path.suffix.lower() == ".npz":
        return save_npz(recording, path)
    if path.suffix.lower() == ".csv":
        return save_csv(recording, path)
    raise RecordingError(f"{path}: unknown recording type {path.suffix!r}, expected .npz or .csv")
