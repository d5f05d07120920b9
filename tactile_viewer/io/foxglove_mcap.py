"""Reconstructed frames as an MCAP file that Foxglove shows without plugins. No Qt.

Written through the Foxglove SDK (``foxglove-sdk``: :func:`foxglove.open_mcap`
and its typed channels), so every message carries Foxglove's own protobuf
schema (``foxglove.Grid``, ``foxglove.SceneUpdate``, ``foxglove.PointCloud``)
in the file, which Foxglove's 3D panel draws as it is. One message per solved
frame on each topic, logged and stamped with the frame's time (UNIX
nanoseconds: the recording's receive clock where it has one, else its ``t``
counted from 1970):

- ``/tactile/stress``: the calibrated sensor stress, pascals, field ``stress``
  (float32); a ``foxglove.Grid`` of one pitch x pitch cell per taxel for a
  regular layout (a rectangle of taxels, moved or not), a
  ``foxglove.PointCloud`` of the taxels' positions for an irregular one.
- ``/tactile/pressure``: the reconstructed normal pressure ``Fz / pitch^2``,
  pascals (the viewer's pressure map), field ``pressure``, the same way.
- ``/tactile/forces``: a ``foxglove.SceneUpdate`` of two entities, replaced
  every frame: ``nodes``, one arrow per node in node order, and ``contacts``,
  one arrow per contact (largest first) with its number as a text label.
- ``/tactile/contacts``: JSON (schema ``tactile_viewer.ContactTotals``) that
  the Plot panel plots: the frame's total force, its shear parameters and
  each contact's identity, resultant and centre (newtons, metres).

Frame ``tactile_skin``: x and y as the layout's, z out of the skin (the
viewer's scene: the surface at z = 0, the elastomer below it). An arrow is
``(Fx, Fy, -Fz)`` times its scale, its tip on the surface where the force
acts, so a press points down into the skin; node arrows are coloured by
``|F|`` (plasma, 0 to the largest node force of the export), a contact's by
its identity (it keeps its colour while it persists). No frame transform is
written: the 3D panel shows the skin in its own frame, and a lab that mounts
the skin on a robot publishes the transform from its link to ``tactile_skin``.

A metadata record ``tactile-viewer.foxglove`` names the source, kernel,
mode, scales, units and the frames left out.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import foxglove
import numpy as np
from foxglove import channels as fc
from foxglove import messages as fm

from solver import SensorGrid
from solver.checks import real_number

from .forces import ForceTable
from .mcap_format import MAGIC
from .recording import written_whole
from .ros2_message import FRAME_ID  # the skin's frame, the same name as in our recordings

__all__ = ["write_foxglove", "FoxgloveExport", "readable_scales", "is_foxglove_export", "TOPICS",
           "CONTACTS_SCHEMA", "METADATA_NAME"]

TOPICS = {"stress": "/tactile/stress", "pressure": "/tactile/pressure", "forces": "/tactile/forces",
          "contacts": "/tactile/contacts"}
METADATA_NAME = "tactile-viewer.foxglove"
_BLOCK = 256  # frames of stress read at once: an MCAP recording is never read whole
# the viewer's arrow colour map (plasma) at five stops, 0 to 1
_PLASMA = np.array([[13, 8, 135], [126, 3, 168], [204, 71, 120], [248, 149, 64], [240, 249, 33]]) / 255
# a contact's colour by its identity; the first is the viewer's resultant red
_CONTACT_COLOURS = ((0.85, 0.1, 0.1), (0.12, 0.47, 0.71), (0.17, 0.63, 0.17), (1.0, 0.5, 0.05),
                    (0.58, 0.4, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5),
                    (0.74, 0.74, 0.13), (0.09, 0.75, 0.81))
_NUMBER = {"type": "number"}
_VECTOR = {"type": "object", "properties": {"fx": _NUMBER, "fy": _NUMBER, "fz": _NUMBER}}
CONTACTS_SCHEMA = {
    "title": "tactile_viewer.ContactTotals", "type": "object",
    "description": "A frame's total force and its contacts' resultants (N) and centres (m)",
    "properties": {
        "frame": {"type": "integer"}, "t": _NUMBER, "total": _VECTOR,
        "shear_ratio": {"type": ["number", "null"]}, "shear_direction_deg": {"type": ["number", "null"]},
        "contact_count": {"type": "integer"},
        "contacts": {"type": "array", "items": {"type": "object", "properties": {
            "identity": {"type": "integer"}, "fx": _NUMBER, "fy": _NUMBER, "fz": _NUMBER, "x": _NUMBER,
            "y": _NUMBER}}},
    },
}


@dataclass(frozen=True)
class FoxgloveExport:
    """What :func:`write_foxglove` wrote.

    Attributes
    ----------
    path : Path
    frames : int
        Frames written (one message each on every topic).
    messages : dict
        Messages per topic.
    arrow_scale, resultant_scale : float
        Metres of arrow per newton of a node force and of a contact's resultant.
    refused : tuple of (int, str)
        Frames left out (the solver refused them or they could not be read), with the reason.
    """

    path: Path
    frames: int
    messages: dict = field(default_factory=dict)
    arrow_scale: float = 0.0
    resultant_scale: float = 0.0
    refused: tuple = ()


def is_foxglove_export(path) -> bool:
    """Whether the file at ``path`` is an export written by :func:`write_foxglove`.

    Cheap (reads its first 4 KiB): the metadata record ``tactile-viewer.foxglove`` is written
    right after the MCAP header. Raises OSError when the file cannot be read.
    """
    with open(path, "rb") as handle:
        head = handle.read(4096)
    return head.startswith(MAGIC) and METADATA_NAME.encode() in head


def readable_scales(table: ForceTable) -> tuple[float, float]:
    """Arrow scales (metres per newton) that read on the skin, as the viewer picks them.

    The largest node force of the table spans three pitches; the largest
    contact resultant (the largest frame total without contacts) half the
    skin's width. A table without load gets the viewer's scales for 50 mN
    per node and 1 N in all.
    """
    width = float(np.ptp(table.positions[:, 0])) + table.pitch
    peak = float(np.linalg.norm(table.forces, axis=-1).max(initial=0.0))
    totals = (np.linalg.norm(np.nan_to_num(table.contact_force), axis=-1) if table.contact_force.size
              else np.linalg.norm(table.forces.sum(axis=1), axis=-1))
    total = float(totals.max(initial=0.0))
    return 3 * table.pitch / (peak or 0.05), width / 2 / (total or 1.0)


def write_foxglove(path, table: ForceTable, stress, *, start_time: float = 0.0,
                   arrow_scale: float | None = None, resultant_scale: float | None = None, refused=(),
                   progress=None) -> FoxgloveExport:
    """Write the solved frames of ``table`` and their stresses as a Foxglove MCAP (module notes).

    The file is written under a temporary name and renamed when whole: a
    failure (or an exception ``progress`` raises) leaves no file.

    Parameters
    ----------
    path : str or Path
        The ``.mcap`` file; an existing one is replaced.
    table : ForceTable
        The solved frames (``table.frames`` index ``stress``).
    stress : (N, m) array-like
        The recording's calibrated stress, pascals, indexed by frame number
        (a :class:`~tactile_viewer.io.recording.Recording`'s ``frames``: read in
        blocks of the table's frames, so a lazy MCAP recording is never read whole).
    start_time : float
        UNIX seconds of ``t = 0`` (a recording's ``received``; default 0).
    arrow_scale, resultant_scale : float, optional
        Metres of arrow per newton, > 0; default :func:`readable_scales`.
    refused : sequence of (int, str)
        Frames left out of ``table`` and why, named in the file's metadata.
    progress : callable, optional
        ``progress(done, total)`` after each block of frames.

    Returns
    -------
    FoxgloveExport
    """
    path = Path(path)
    start_time = real_number("start_time", start_time, rule="finite UNIX seconds", valid=math.isfinite)
    default_arrow, default_resultant = readable_scales(table)
    scales = []
    for name, value, default in (("arrow_scale", arrow_scale, default_arrow),
                                 ("resultant_scale", resultant_scale, default_resultant)):
        scales.append(default if value is None else real_number(
            name, value, rule="metres per newton, finite and > 0",
            valid=lambda v: math.isfinite(v) and v > 0))
    count = len(table.frames)
    shape = tuple(getattr(stress, "shape", None) or np.shape(stress))
    taxels = len(table.positions)
    if len(shape) != 2 or shape[1] != taxels or (count and int(table.frames.max()) >= shape[0]):
        raise ValueError(f"stress must be the recording's (N, {taxels}) frames, N above every frame of the "
                         f"table (up to {int(table.frames.max(initial=-1))}), got shape {shape}")
    layout = _MapGeometry(table)
    peak = float(np.linalg.norm(table.forces, axis=-1).max(initial=0.0)) or 1.0
    counts = dict.fromkeys(TOPICS.values(), 0)
    with written_whole(path) as temporary:
        context = foxglove.Context()  # its own: a file's channels reach no other sink of the process
        writer = foxglove.open_mcap(temporary, allow_overwrite=True, context=context)
        try:
            writer.write_metadata(METADATA_NAME, _metadata(table, scales, refused, start_time))
            channels = layout.channels(context) | {
                TOPICS["forces"]: fc.SceneUpdateChannel(TOPICS["forces"], context=context,
                                                        metadata={"units": "m, N"}),
                TOPICS["contacts"]: foxglove.Channel(TOPICS["contacts"], schema=CONTACTS_SCHEMA,
                                                     context=context, metadata={"units": "N, m, degrees"})}
            for first in range(0, count, _BLOCK):
                rows = np.arange(first, min(first + _BLOCK, count))
                block = np.asarray(stress[table.frames[rows]], dtype=float).reshape(len(rows), -1)
                for row, sensed in zip(rows, block, strict=True):
                    stamp = round((start_time + float(table.t[row])) * 1e9)
                    forces = table.forces[row]
                    messages = {TOPICS["stress"]: layout.message(sensed, "stress", stamp),
                                TOPICS["pressure"]: layout.message(forces[:, 2] / table.pitch**2, "pressure",
                                                                   stamp),
                                TOPICS["forces"]: _scene(table, row, stamp, scales, peak),
                                TOPICS["contacts"]: _totals(table, row, stamp)}
                    for topic, message in messages.items():
                        channels[topic].log(message, log_time=stamp)
                        counts[topic] += 1
                if progress is not None:
                    progress(int(rows[-1]) + 1, count)
        finally:
            writer.close()
    return FoxgloveExport(path, count, counts, scales[0], scales[1], tuple(refused))


class _MapGeometry:
    # the maps' geometry: a Grid for a rectangle of taxels at one pitch, a PointCloud otherwise
    def __init__(self, table: ForceTable):
        self.positions = np.asarray(table.positions, dtype=float)
        self.pitch = float(table.pitch)
        self.shape = tuple(table.shape)
        self.regular = len(self.shape) == 2 and _is_lattice(self.positions, self.shape, self.pitch)

    def channels(self, context) -> dict:
        kind = fc.GridChannel if self.regular else fc.PointCloudChannel
        return {TOPICS[name]: kind(TOPICS[name], context=context, metadata={"units": "Pa", "field": name})
                for name in ("stress", "pressure")}

    def message(self, values, name: str, stamp: int):
        values = np.asarray(values, dtype="<f4")
        float32 = fm.PackedElementFieldNumericType.Float32
        if self.regular:
            ny, nx = self.shape
            corner = self.positions[0] - self.pitch / 2  # node 0 is the lattice's lowest x and y
            return fm.Grid(timestamp=_timestamp(stamp), frame_id=FRAME_ID,
                           pose=_pose(float(corner[0]), float(corner[1]), 0.0), column_count=nx,
                           cell_size=fm.Vector2(x=self.pitch, y=self.pitch), row_stride=4 * nx, cell_stride=4,
                           fields=[fm.PackedElementField(name=name, offset=0, type=float32)],
                           data=values.tobytes())
        points = np.column_stack([self.positions, np.zeros(len(values)), values]).astype("<f4")
        return fm.PointCloud(timestamp=_timestamp(stamp), frame_id=FRAME_ID, pose=_pose(0.0, 0.0, 0.0),
                             point_stride=16,
                             fields=[fm.PackedElementField(name=axis, offset=4 * i, type=float32)
                                     for i, axis in enumerate(("x", "y", "z", name))],
                             data=points.tobytes())


def _is_lattice(positions, shape, pitch) -> bool:
    ny, nx = shape
    lattice = SensorGrid.regular(nx, ny, pitch, pitch).positions
    return bool(np.allclose(positions - positions[0], lattice - lattice[0], rtol=0, atol=1e-3 * pitch))


def _timestamp(stamp: int):
    return fm.Timestamp(stamp // 1_000_000_000, stamp % 1_000_000_000)


def _pose(x: float, y: float, z: float, rotation=(0.0, 0.0, 0.0, 1.0)):
    qx, qy, qz, qw = rotation
    return fm.Pose(position=fm.Vector3(x=x, y=y, z=z), orientation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw))


def _arrows(tips, forces, scale: float, colours, cap: float) -> list:
    """Arrows of ``(Fx, Fy, -Fz) * scale`` ending at ``tips (k, 3)``, one per row of ``forces (k, 3)``.

    The viewer's arrow shape (head 0.3 of the length) grown with the length; its
    width is capped at ``cap`` metres so a long arrow does not cover its neighbours.
    """
    vectors = np.column_stack([forces[:, 0], forces[:, 1], -forces[:, 2]]) * scale
    lengths = np.linalg.norm(vectors, axis=1)
    tails = (np.asarray(tips, dtype=float) - vectors).tolist()
    rotations = _rotations_from_x(vectors, lengths).tolist()
    shaft, head = np.minimum(0.1 * lengths, cap / 2), np.minimum(0.24 * lengths, cap)
    shapes = zip(tails, rotations, lengths.tolist(), shaft.tolist(), head.tolist(), colours, strict=True)
    return [fm.ArrowPrimitive(pose=_pose(*tail, rotation), shaft_length=0.7 * length,
                              head_length=0.3 * length, shaft_diameter=s, head_diameter=h,
                              color=_colour(*colour))
            for tail, rotation, length, s, h, colour in shapes]


def _rotations_from_x(vectors, lengths) -> np.ndarray:
    # (k, 4) unit quaternions (x, y, z, w) turning +x onto each vector: the half-way rotation,
    # (0, -uz, uy, 1 + ux) normalised; the identity for a zero vector, half a turn about z for -x
    unit = np.divide(vectors, lengths[:, None], out=np.zeros_like(vectors), where=lengths[:, None] > 0)
    q = np.column_stack([np.zeros(len(unit)), -unit[:, 2], unit[:, 1], 1.0 + unit[:, 0]])
    q[lengths == 0] = (0.0, 0.0, 0.0, 1.0)
    q[(lengths > 0) & (unit[:, 0] < -1 + 1e-12)] = (0.0, 0.0, 1.0, 0.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _colour(r, g, b, a=1.0):
    return fm.Color(r=r, g=g, b=b, a=a)


def _plasma(shares) -> list:
    # (k,) shares of the colour range, 0 to 1, as (r, g, b, 1) of the viewer's arrow colour map
    at = np.clip(np.asarray(shares, dtype=float), 0.0, 1.0) * (len(_PLASMA) - 1)
    rgb = np.column_stack([np.interp(at, np.arange(len(_PLASMA)), _PLASMA[:, i]) for i in range(3)])
    return np.column_stack([rgb, np.ones(len(rgb))]).tolist()


def _scene(table: ForceTable, row: int, stamp: int, scales, peak: float):
    arrow_scale, resultant_scale = scales
    forces = table.forces[row]
    tips = np.column_stack([table.positions, np.zeros(len(forces))])
    shares = np.linalg.norm(forces, axis=1) / peak  # the colour range: 0 to the export's largest node force
    nodes = _arrows(tips, forces, arrow_scale, _plasma(shares), table.pitch / 2)
    slots = np.flatnonzero(table.contact_identity[row])
    identities = table.contact_identity[row, slots].tolist()
    colours = [(*_CONTACT_COLOURS[(k - 1) % len(_CONTACT_COLOURS)], 1.0) for k in identities]
    totals = table.contact_force[row, slots]
    centres = np.column_stack([table.contact_centre[row, slots], np.zeros(len(slots))])
    arrows = _arrows(centres, totals, resultant_scale, colours, 2 * table.pitch)
    # each label at its arrow's tail, where it covers no arrow
    texts = [fm.TextPrimitive(pose=_pose(*arrow_tail), billboard=True, font_size=14.0, scale_invariant=True,
                              color=_colour(*colour), text=f"#{identity} {1e3 * total[2]:.0f} mN")
             for arrow_tail, colour, identity, total in zip(
                 (centres - np.column_stack([totals[:, :2], -totals[:, 2]]) * resultant_scale).tolist(),
                 colours, identities, totals, strict=True)]
    entity = dict(timestamp=_timestamp(stamp), frame_id=FRAME_ID)
    return fm.SceneUpdate(entities=[
        fm.SceneEntity(id="nodes", arrows=nodes,
                       metadata=[fm.KeyValuePair(key="metres_per_newton", value=repr(arrow_scale))],
                       **entity),
        fm.SceneEntity(id="contacts", arrows=arrows, texts=texts,
                       metadata=[fm.KeyValuePair(key="metres_per_newton", value=repr(resultant_scale))],
                       **entity)])


def _number(value):
    value = float(value)
    return value if math.isfinite(value) else None  # JSON has no nan


def _totals(table: ForceTable, row: int, stamp: int) -> bytes:
    total = table.forces[row].sum(axis=0)
    contacts = [{"identity": int(table.contact_identity[row, slot]),
                 **dict(zip(("fx", "fy", "fz"), map(_number, table.contact_force[row, slot]), strict=True)),
                 **dict(zip(("x", "y"), map(_number, table.contact_centre[row, slot]), strict=True))}
                for slot in np.flatnonzero(table.contact_identity[row])]
    message = {"timestamp": {"sec": stamp // 1_000_000_000, "nsec": stamp % 1_000_000_000},
               "frame": int(table.frames[row]), "t": float(table.t[row]),
               "total": dict(zip(("fx", "fy", "fz"), map(_number, total), strict=True)),
               "shear_ratio": _number(table.shear_ratio[row]),
               "shear_direction_deg": _number(math.degrees(table.shear_direction[row])),
               "contact_count": len(contacts), "contacts": contacts}
    return json.dumps(message, allow_nan=False).encode("utf-8")


def _metadata(table: ForceTable, scales, refused, start_time: float) -> dict:
    listed = ", ".join(f"{frame}: {reason}" for frame, reason in list(refused)[:20])
    cheaper = np.flatnonzero(table.fallback != "")
    why = "; ".join(f"{table.frames[k]}: {table.fallback[k]}" for k in cheaper[:20])
    fields = {"source": table.source, "kernel": table.kernel, "mode": table.mode, "frames": len(table.frames),
              "refused_frames": len(refused), "refused": listed + (" ..." if len(refused) > 20 else ""),
              # frames whose forces are a cheaper member than the accurate path, and why
              "fallback_frames": len(cheaper), "fallback": why + (" ..." if len(cheaper) > 20 else ""),
              "start_time_s": repr(start_time), "arrow_scale_m_per_N": repr(scales[0]),
              "resultant_scale_m_per_N": repr(scales[1]), "frame_id": FRAME_ID, "pitch_m": repr(table.pitch),
              "thickness_m": repr(table.thickness), "shape": "x".join(map(str, table.shape[::-1])),
              "units": "stress and pressure Pa, forces N, positions m, time UNIX ns"}
    return {key: str(value) for key, value in fields.items()}
