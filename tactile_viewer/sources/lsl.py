"""Lab Streaming Layer: what we publish (:class:`ForceOutlet`) and the stream description convention. No Qt.

Two stream types, as a lab's other LSL programs expect them (the user documentation's LSL section):

``TactileForce``
    The reconstructed force of every node, three channels per node in node
    order: ``node0_Fx, node0_Fy, node0_Fz, node1_Fx, ...``, newtons, float32.
    Nodes are the sensors (the solver's force nodes sit at the taxels).
``Tactile``
    The calibrated normal stress of every taxel, ``taxel0, taxel1, ...``,
    pascals, float32 (compression positive).

Each sample is stamped on LSL's clock (:func:`pylsl.local_clock`) with the
time its frame was received (:func:`clock_offset` converts a receive clock).

Description (``<desc>``) of every stream, read back by
:func:`layout_from_description`, so that any program (ours included) can
draw or reconstruct it::

    <channels><channel><label>node12_Fx</label><unit>newtons</unit><type>Force</type></channel>...</channels>
    <layout>
      <nx>16</nx><ny>16</ny>            (or <taxels>m</taxels> for an irregular skin; <cols>/<rows> read too)
      <pitch>0.004</pitch>              metres
      <thickness>0.004</thickness>      metres, the elastomer over the sensors
      <poisson_ratio>0.5</poisson_ratio> <sensor_size>0</sensor_size>   (optional)
      <positions>x0 y0 x1 y1 ...</positions>  metres, node/taxel k at (x_k, y_k) (optional for a grid)
      <units>Pa</units> <gain>1</gain> <offset>0</offset>  how sample values become pascals (optional)
    </layout>

Numbers are plain decimal text; a list is numbers separated by spaces or
commas; ``gain`` and ``offset`` are one number or one per taxel. The keys
are those of a layout file (:func:`tactile_viewer.io.layout.load_layout`).
"""

from __future__ import annotations

import math
import re
import time

import numpy as np

from solver import SensorGrid
from solver.checks import real_number, shown

from ..io.layout import SensorLayout, layout_from_fields
from ..io.recording import geometry_fields

__all__ = ["FORCE_TYPE", "STRESS_TYPE", "FORCE_COMPONENTS", "ForceOutlet", "clock_offset", "describe_layout",
           "describe_channels", "force_labels", "stress_labels", "layout_from_description"]

FORCE_TYPE = "TactileForce"
STRESS_TYPE = "Tactile"
FORCE_COMPONENTS = ("Fx", "Fy", "Fz")
FORCE_UNIT = "newtons"  # spelled out, as the XDF meta-data conventions write units
STRESS_UNIT = "pascals"
_WHOLE_KEYS = ("nx", "ny", "taxels")
_NUMBER_KEYS = ("pitch", "thickness", "poisson_ratio", "sensor_size")
_LIST_KEYS = ("gain", "offset")  # one number, or one per taxel
_ALIASES = {"cols": "nx", "rows": "ny"}  # the urdf_tactile names of a grid's shape
_SEPARATORS = re.compile(r"[\s,]+")


def force_labels(nodes: int) -> list[str]:
    """``node0_Fx, node0_Fy, node0_Fz, node1_Fx, ...``: the channel labels of a ``TactileForce`` stream."""
    return [f"node{k}_{c}" for k in range(nodes) for c in FORCE_COMPONENTS]


def stress_labels(taxels: int) -> list[str]:
    """``taxel0, taxel1, ...``: the channel labels of a ``Tactile`` stream."""
    return [f"taxel{k}" for k in range(taxels)]


def _number_text(value) -> str:
    return repr(float(value))  # shortest text that reads back as the same float


def describe_channels(desc, labels, *, unit: str, kind: str) -> None:
    """Append the standard ``<channels>`` of LSL's meta-data conventions to ``desc`` (a pylsl XMLElement).

    Each channel gets ``<label>``, ``<unit>`` and ``<type>`` (``kind``).
    """
    channels = desc.append_child("channels")
    for label in labels:
        channel = channels.append_child("channel")
        channel.append_child_value("label", label)
        channel.append_child_value("unit", unit)
        channel.append_child_value("type", kind)


def describe_layout(desc, layout: SensorLayout, *, positions: bool = False) -> None:
    """Append ``<layout>`` (module notes) for ``layout`` to ``desc``, a pylsl XMLElement.

    Parameters
    ----------
    desc : pylsl XMLElement
    layout : SensorLayout
        The skin, and how the stream's values become pascals.
    positions : bool
        Write every node's position even for a grid that sits where a grid
        sits by default (what a reader that does not know our grid needs).
    """
    fields = geometry_fields(layout.grid) | layout.calibration.fields()
    if positions:
        fields["positions"] = layout.grid.positions
    element = desc.append_child("layout")
    for key, value in fields.items():
        if isinstance(value, str):
            text = value
        elif isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            text = str(int(value))
        else:
            text = " ".join(_number_text(v) for v in np.ravel(value))
        element.append_child_value(key, text)


def layout_from_description(desc) -> SensorLayout:
    """The layout a stream's ``<desc>`` declares in its ``<layout>`` element (module notes).

    Parameters
    ----------
    desc : pylsl XMLElement
        ``StreamInfo.desc()`` of a stream's full info (an inlet's ``info()``;
        what a resolve returns carries no description).

    Raises
    ------
    ValueError
        When there is no ``<layout>``, or naming the element that is missing
        or wrong and what it holds.
    """
    element = desc.child("layout")
    if element.empty():
        raise ValueError("the stream's description has no <layout> element")
    spec: dict = {}
    child = element.first_child()
    while not child.empty():
        name = child.name()
        key = _ALIASES.get(name, name)
        text = child.child_value().strip()
        try:
            spec[key] = _field_value(key, text)
        except ValueError as exc:
            raise ValueError(f"<layout> <{name}>: {exc}") from None
        child = child.next_sibling()
    if "positions" in spec:
        flat = spec["positions"]
        if len(flat) % 2:
            raise ValueError(f"<layout> <positions> must hold x y pairs, got {len(flat)} numbers")
        spec["positions"] = np.reshape(flat, (-1, 2))
    try:
        return layout_from_fields(spec)
    except ValueError as exc:
        raise ValueError(f"<layout>: {exc}") from None


def _field_value(key: str, text: str):
    # the text of one <layout> element as the value a layout file holds for that key
    if key == "units":
        return text
    if key in _WHOLE_KEYS:
        if not re.fullmatch(r"\+?\d{1,9}", text):
            raise ValueError(f"expected a whole number, got {text!r}")
        return int(text)
    words = [w for w in _SEPARATORS.split(text) if w]
    try:
        values = [float(w) for w in words]
    except ValueError:
        raise ValueError(f"expected numbers, got {text[:60]!r}") from None
    if key in _NUMBER_KEYS:
        if len(values) != 1:
            raise ValueError(f"expected one number, got {text[:60]!r}")
        return values[0]
    if key in _LIST_KEYS and len(values) == 1:
        return values[0]
    return np.array(values)


def clock_offset(clock, *, tries: int = 5) -> float:
    """Seconds to add to a reading of ``clock()`` to get LSL's clock (:func:`pylsl.local_clock`).

    ``clock`` is a receive clock in seconds (``LiveSource.now``, ``time.perf_counter``);
    both are monotonic, so the offset holds while the clock runs. It is read
    between two LSL clock readings, keeping the closest pair of ``tries``
    (a thread switch between the readings widens the pair, not the error).
    """
    from pylsl import local_clock

    best = (math.inf, 0.0)
    for _ in range(tries):
        before = local_clock()
        reading = clock()
        after = local_clock()
        best = min(best, (after - before, (before + after) / 2 - reading))
    return best[1]


class ForceOutlet:
    """Publishes reconstructed node forces (``TactileForce``), optionally the stress (``Tactile``), over LSL.

    Parameters
    ----------
    grid : SensorGrid
        The skin whose nodes the forces belong to (its positions, metres,
        go into the description).
    name : str
        The streams' LSL name (both streams share it; their types differ).
    source_id : str or None
        A stable identifier of what is published (a board's port, say): LSL
        inlets reconnect across a restart to a stream with the same one. The
        stress stream gets ``source_id + "/stress"``. None: no identifier.
    stress : bool
        Also publish the calibrated stress (pascals), default False.
    nominal_rate : float
        The frames' nominal rate in hertz; 0 (the default) for an irregular
        rate, as a live board that the solver follows frame by frame.

    Notes
    -----
    :meth:`push` copies into buffers made here and hands them to liblsl in one
    call per stream (``push_chunk`` of one sample with its stamp): no
    allocation per frame.
    """

    def __init__(self, grid: SensorGrid, *, name: str = "tactile-viewer", source_id: str | None = None,
                 stress: bool = False, nominal_rate: float = 0.0):
        if not isinstance(grid, SensorGrid):
            raise TypeError(f"grid must be a SensorGrid, got {type(grid).__name__}")
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"name must be a non-empty string, got {name!r}")
        if source_id is not None and not isinstance(source_id, str):
            raise ValueError(f"source_id must be a string or None, got {source_id!r}")
        if not isinstance(stress, bool):
            raise ValueError(f"stress must be True or False, got {shown(stress)}")
        rate = real_number("nominal_rate", nominal_rate, rule="a finite number of hertz >= 0 (0: irregular)",
                           valid=lambda r: math.isfinite(r) and r >= 0)
        import pylsl

        self.grid = grid
        self.name = name
        self.source_id = source_id
        m = grid.size
        layout = SensorLayout(grid)  # values in pascals already: unit gain, no offset
        info = pylsl.StreamInfo(name, FORCE_TYPE, 3 * m, rate, pylsl.cf_float32, source_id or "")
        describe_channels(info.desc(), force_labels(m), unit=FORCE_UNIT, kind="Force")
        describe_layout(info.desc(), layout, positions=True)
        _describe_origin(info.desc())
        self.force_info = info
        self._forces = np.zeros((1, 3 * m), dtype=np.float32)
        self._force_outlet = pylsl.StreamOutlet(info)
        self.stress_info = self._stress_outlet = self._stress = None
        if stress:
            info = pylsl.StreamInfo(name, STRESS_TYPE, m, rate, pylsl.cf_float32,
                                    f"{source_id}/stress" if source_id else "")
            describe_channels(info.desc(), stress_labels(m), unit=STRESS_UNIT, kind="Stress")
            describe_layout(info.desc(), layout)
            _describe_origin(info.desc())
            self.stress_info = info
            self._stress = np.zeros((1, m), dtype=np.float32)
            self._stress_outlet = pylsl.StreamOutlet(info)
        self.pushed = 0  # frames published

    @property
    def publishes_stress(self) -> bool:
        return self._stress is not None

    @property
    def closed(self) -> bool:
        return self._force_outlet is None

    def push(self, forces, *, stamp: float, stress=None) -> None:
        """Publish one frame's node forces (and its stress) stamped ``stamp``.

        Parameters
        ----------
        forces : (m, 3) ndarray
            Fx, Fy, Fz of every node, newtons (``Reconstruction.forces``).
        stamp : float
            When the frame was received, seconds on LSL's clock
            (:func:`pylsl.local_clock`; :func:`clock_offset` converts).
        stress : (m,) ndarray or None
            The frame's calibrated stress, pascals, published when the outlet
            was made with ``stress=True`` (None: only the forces).

        Raises
        ------
        ValueError
            For a closed outlet, a shape other than the grid's, a value not
            finite, or stress given to an outlet made without it.
        """
        if self._force_outlet is None:
            raise ValueError("the outlet is closed")
        row = self._forces
        if np.shape(forces) != (self.grid.size, 3):
            raise ValueError(f"forces must have shape ({self.grid.size}, 3) (nodes, Fx Fy Fz), got "
                             f"{np.shape(forces)}")
        if not (isinstance(stamp, (float, int, np.floating)) and math.isfinite(stamp) and stamp > 0):
            raise ValueError("stamp must be a positive finite number of seconds on LSL's clock, got "
                             f"{shown(stamp)}")
        np.copyto(row.reshape(-1, 3), forces, casting="same_kind")
        if not np.isfinite(row).all():
            raise ValueError("forces must be finite numbers of newtons (NaN or beyond float32 found)")
        if stress is not None:
            if self._stress is None:
                raise ValueError("stress given, but the outlet publishes none (make it with stress=True)")
            if np.shape(stress) != (self.grid.size,):
                raise ValueError(f"stress must have shape ({self.grid.size},) (taxels), got "
                                 f"{np.shape(stress)}")
            np.copyto(self._stress[0], stress, casting="same_kind")
            if not np.isfinite(self._stress).all():
                raise ValueError("stress must be finite numbers of pascals (NaN or beyond float32 found)")
        self._force_outlet.push_chunk(row, float(stamp))
        if stress is not None:
            self._stress_outlet.push_chunk(self._stress, float(stamp))
        self.pushed += 1

    def have_consumers(self, *, stress: bool = False) -> bool:
        """Whether any inlet reads the force stream now (with ``stress``: the stress stream)."""
        outlet = self._stress_outlet if stress else self._force_outlet
        return outlet is not None and outlet.have_consumers()

    def close(self) -> None:
        """Withdraw the streams from the network (again: nothing)."""
        # liblsl destroys an outlet when pylsl's object goes (its __del__)
        self._force_outlet = self._stress_outlet = None

    def __enter__(self) -> ForceOutlet:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _describe_origin(desc) -> None:
    from importlib import metadata

    try:
        version = metadata.version("tactile-viewer")
    except metadata.PackageNotFoundError:  # run from a source tree that was never installed
        version = "unknown"
    acquisition = desc.append_child("acquisition")
    acquisition.append_child_value("manufacturer", "tactile-viewer")
    acquisition.append_child_value("software_version", version)
    acquisition.append_child_value("created", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
