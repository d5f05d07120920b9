"""Sensor layout files: where the taxels are, the elastomer, and how raw values become pascals.

A layout JSON names the geometry (``nx`` and ``ny``, or ``taxels`` and
``positions``; ``pitch``, ``thickness``, optional ``poisson_ratio`` and
``sensor_size``) and the calibration of the raw values (``units``, ``gain``,
``offset``). :func:`load_layout` reads it and :func:`save_layout` writes it;
the geometry goes through the same reader and writer as every recording
(:func:`tactile_viewer.io.recording.grid_from_fields`). No Qt.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from solver import SensorGrid

from .recording import (
    RAW_UNITS,
    StressCalibration,
    geometry_fields,
    grid_from_fields,
    json_ready,
    per_taxel,
    raw_to_pascals,
)

__all__ = ["LayoutError", "SensorLayout", "layout_from_fields", "load_layout", "save_layout", "RAW_UNITS"]


class LayoutError(ValueError):
    """A sensor layout file that cannot be used; the message names the file and the problem."""


@dataclass(frozen=True, eq=False)
class SensorLayout:
    """How a board's raw values map onto the skin.

    ``pascals = gain * (raw - offset) * scale(units)`` per taxel, where
    ``scale`` is 1, 1e3 or 1e6 for ``"Pa"``, ``"kPa"``, ``"MPa"`` and 1 for
    ``"counts"`` (the gain then is pascals per count).

    Attributes
    ----------
    grid : SensorGrid
    units : str
        One of ``"Pa"``, ``"kPa"``, ``"MPa"``, ``"counts"``.
    gain : (m,) ndarray
    offset : (m,) ndarray
        Raw units.
    """

    grid: SensorGrid
    units: str = "Pa"
    gain: np.ndarray = field(default=1.0)
    offset: np.ndarray = field(default=0.0)

    def __post_init__(self):
        m = self.grid.size
        # one set of rules for a calibration, the recordings' (units known, a finite value per taxel)
        calibration = StressCalibration(self.units, per_taxel(self.gain, "gain", m),
                                        per_taxel(self.offset, "offset", m))
        object.__setattr__(self, "gain", calibration.gain)
        object.__setattr__(self, "offset", calibration.offset)

    @property
    def count(self) -> int:
        """Values per frame."""
        return self.grid.size

    @property
    def calibration(self) -> StressCalibration:
        """Its units, gain and offset, as a recording keeps them (no tare)."""
        return StressCalibration(self.units, self.gain, self.offset)

    def to_pascals(self, raw) -> np.ndarray:
        """``(m,)`` or ``(T, m)`` raw values to pascals."""
        return raw_to_pascals(raw, self.units, self.gain, self.offset)


def load_layout(path) -> SensorLayout:
    """Read a sensor layout JSON file.

    Keys: ``nx``, ``ny``, ``pitch``, ``thickness`` (metres); optional
    ``poisson_ratio`` (the elastomer's nu, default 0.5), ``sensor_size`` (side
    of a square taxel, metres, default 0: point sensors), ``positions``
    ([[x, y], ...] metres), ``units``, ``gain``, ``offset`` (a number or one per
    taxel). Files written before nu and the taxel size were recorded have
    neither key and open with the defaults.

    Raises
    ------
    LayoutError
        The message names the file and the key that is wrong.
    """
    path = Path(path)
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LayoutError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except RecursionError:  # arrays nested past the parser's depth (100,000 '[')
        raise LayoutError(f"{path}: not a layout: JSON nested too deep to read") from None
    except ValueError as exc:  # not JSON, not text, or a number of over 4300 digits
        raise LayoutError(f"{path}: not JSON ({exc})") from None
    if not isinstance(spec, dict):
        raise LayoutError(f"{path}: expected a JSON object, got {type(spec).__name__}")
    try:
        return layout_from_fields(spec)
    except ValueError as exc:
        raise LayoutError(f"{path}: {exc}") from None


def layout_from_fields(spec: dict) -> SensorLayout:
    """A layout from the keys of a layout file (:func:`load_layout`), wherever they were read.

    Also how a Lab Streaming Layer stream's ``<layout>`` description becomes a
    layout (:mod:`tactile_viewer.sources.lsl`).

    Raises
    ------
    ValueError
        Naming the key that is missing or wrong (the caller names where the keys came from).
    """
    counts = ("taxels",) if "taxels" in spec else ("nx", "ny")
    missing = [k for k in (*counts, "pitch", "thickness") if k not in spec]
    if missing:
        raise ValueError(f"missing {', '.join(repr(k) for k in missing)}")
    try:
        if not all(isinstance(spec[k], int) and not isinstance(spec[k], bool) for k in counts):
            raise ValueError(f"{' and '.join(counts)} must be whole numbers, got "
                             f"{' and '.join(repr(spec[k]) for k in counts)}")
        for key in ("pitch", "thickness"):
            if isinstance(spec[key], bool) or not isinstance(spec[key], (int, float)):
                raise ValueError(f"{key} must be a number of metres, got {spec[key]!r}")
        # SensorGrid checks nu and the taxel size (a string or a bool is no number there either)
        grid = grid_from_fields(pitch=float(spec["pitch"]), thickness=float(spec["thickness"]),
                                positions=spec.get("positions"), poisson_ratio=spec.get("poisson_ratio", 0.5),
                                sensor_size=spec.get("sensor_size", 0.0), **{k: spec[k] for k in counts})
        return SensorLayout(grid, spec.get("units", "Pa"), spec.get("gain", 1.0), spec.get("offset", 0.0))
    except TypeError as exc:
        raise ValueError(str(exc)) from None


def save_layout(layout: SensorLayout, path) -> Path:
    """Write ``layout`` as the JSON file :func:`load_layout` reads (nu and the taxel size always written).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    spec = json_ready(geometry_fields(layout.grid)) | json_ready(layout.calibration.fields())
    path.write_text(json.dumps(spec, indent=2) + "\n", encoding="utf-8")
    return path
