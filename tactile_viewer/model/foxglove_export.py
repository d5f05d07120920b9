"""A recording's reconstructed frames as a Foxglove MCAP: solved, then written. No Qt.

The frames are solved by :func:`~tactile_viewer.model.force_tables.reconstruct_frames`,
as the whole-recording force export solves them (the window's solver and
parameters, contacts numbered from the first frame), and written by
:func:`tactile_viewer.io.foxglove_mcap.write_foxglove` with the recording's
stresses. A frame that cannot be read or that the solver refuses is left out,
counted and named (:attr:`FoxgloveExport.refused`, the file's metadata); the
others are written.

``tactile-batch --format foxglove`` writes the same file from its own chunked
solve (:func:`save_force_file`, :func:`force_file_ending`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from solver.arguments import check_parameters

from ..io.files import load
from ..io.forces import ForceTable, save_forces
from ..io.foxglove_mcap import FoxgloveExport, write_foxglove
from ..io.recording import Recording
from .force_tables import reconstruct_frames
from .worker import Cancelled

__all__ = ["export_foxglove", "save_force_file", "force_file_ending", "FOXGLOVE_FORMAT", "FoxgloveExport"]

FOXGLOVE_FORMAT = "foxglove"  # tactile-batch --format foxglove: <name>.forces.mcap
_ENDINGS = {"npz": ".npz", "csv": ".csv", FOXGLOVE_FORMAT: ".mcap"}


def export_foxglove(recording: Recording, reconstructor, path, *, shear_ratio=None, shear_direction=None,
                    arrow_scale=None, resultant_scale=None, source: str = "",
                    progress=None) -> FoxgloveExport:
    """Solve every frame of ``recording`` and write them as a Foxglove MCAP (:func:`write_foxglove`).

    Parameters
    ----------
    recording : Recording
    reconstructor : solver.Reconstructor
        The solver (the window's own: a solver may be shared between threads).
    path : str or Path
        The ``.mcap`` file, written whole or not at all.
    shear_ratio, shear_direction : float, optional
        Both None (default): found for each frame; given: fixed (direction in radians).
    arrow_scale, resultant_scale : float, optional
        Metres of arrow per newton of a node force and of a contact's resultant;
        default :func:`~tactile_viewer.io.foxglove_mcap.readable_scales` of the solved frames.
    source : str
        What the file names as its source (default the recording's description).
    progress : callable, optional
        ``progress(done, total) -> bool`` over the solving and then the writing
        (``total`` is twice the frames); returning False cancels
        (:class:`Cancelled` is raised, nothing is written).

    Returns
    -------
    FoxgloveExport
        The file, its message counts per topic and the frames left out with their reasons.

    Raises
    ------
    ValueError
        Bad parameters, a path not ending in ``.mcap``, or no frame that could be solved
        (the first one's reason given).
    """
    check_parameters(shear_ratio, shear_direction, None)
    path = Path(path)
    if path.suffix.lower() != ".mcap":
        raise ValueError(f"path must end in .mcap (Foxglove opens MCAP files by their ending), "
                         f"got {str(path)!r}")
    count = len(recording)

    def solving(done, total):
        return True if progress is None else progress(done, 2 * count)

    def writing(done, total):
        # the written frames' share of the second half (refused frames are not written)
        if progress is not None and progress(count + round(done * count / max(total, 1)), 2 * count) is False:
            raise Cancelled(f"cancelled after writing {done} of {total} frames")

    refused: list = []
    table = reconstruct_frames(recording, reconstructor, shear_ratio=shear_ratio,
                               shear_direction=shear_direction, progress=solving, refused=refused)
    if not len(table.frames):
        reason = f": frame {refused[0][0]}: {refused[0][1]}" if refused else ""
        raise ValueError(f"no frame of the recording could be solved ({len(refused)} refused{reason})")
    if source:
        table = replace(table, source=source)
    return write_foxglove(path, table, recording.frames, start_time=recording.received or 0.0,
                          arrow_scale=arrow_scale, resultant_scale=resultant_scale, refused=refused,
                          progress=writing)


def force_file_ending(fmt: str) -> str:
    """The file ending of a batch output format: ``.npz``, ``.csv``, ``.mcap`` (``foxglove``)."""
    if fmt not in _ENDINGS:
        raise ValueError(f"--format must be one of {tuple(_ENDINGS)}, got {fmt!r}")
    return _ENDINGS[fmt]


def save_force_file(table: ForceTable, path, *, source: str, layout=None, topic=None, field=None) -> Path:
    """Write a force table in the format its ending names: a force export, or for ``.mcap`` a Foxglove file.

    A Foxglove file draws the stresses too: they are read from the recording at
    ``source`` (its path; a ROS 2 bag through ``layout``, ``topic`` and ``field``,
    as :func:`tactile_viewer.io.files.load` takes them), the frames' times on its
    receive clock.
    """
    path = Path(path)
    if path.suffix.lower() != ".mcap":
        return save_forces(table, path, source=source)
    bag = {} if layout is None else {"layout": layout, "topic": topic, "field": field}  # ours take none
    recording = load(source, **bag)
    write_foxglove(path, table, recording.frames, start_time=recording.received or 0.0)
    return path
