"""Sensor layouts: where the taxels are and how thick the elastomer is."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .arrays import read_only

__all__ = ["SensorGrid"]


def _positive_finite(name: str, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number of metres, got {value!r}") from None
    if not math.isfinite(number) or number <= 0.0:
        raise ValueError(f"{name} must be a positive finite number of metres, got {value!r}")
    return number


def _positive_count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    if value < 1:
        raise ValueError(
            f"{name} must be a positive integer (a grid needs at least one taxel), got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class SensorGrid:
    """A skin: sensor positions under an elastomer layer of uniform thickness.

    Nodes (where forces are reconstructed) coincide with the sensors.

    Attributes
    ----------
    positions : (m, 2) ndarray
        Sensor (and node) positions on the surface plane, metres. Read-only.
        For a regular grid the order is row-major with x fastest: node
        ``k = iy * nx + ix``.
    thickness : float
        Elastomer thickness ``h`` between the surface and the sensors, metres.
    pitch : float
        Side of the square cell each node stands for, metres.
    shape : tuple of int
        ``(ny, nx)`` for a regular grid, so that a frame reshapes to it;
        ``(m,)`` for an irregular layout.
    """

    positions: np.ndarray
    thickness: float
    pitch: float
    shape: tuple

    def __post_init__(self):
        positions = read_only(self.positions)
        if positions.ndim != 2 or positions.shape[1] != 2 or positions.shape[0] < 1:
            raise ValueError(
                f"positions must have shape (m, 2) with m >= 1, got shape {positions.shape}"
            )
        if not np.all(np.isfinite(positions)):
            raise ValueError("positions must be finite, got NaN or inf")
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "thickness", _positive_finite("thickness", self.thickness))
        object.__setattr__(self, "pitch", _positive_finite("pitch", self.pitch))
        shape = tuple(self.shape)
        if not all(isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 1 for s in shape):
            raise ValueError(f"shape entries must be whole numbers >= 1, got {self.shape!r}")
        shape = tuple(int(s) for s in shape)
        if math.prod(shape) != positions.shape[0]:
            raise ValueError(
                f"shape {shape} does not hold the {positions.shape[0]} positions given"
            )
        object.__setattr__(self, "shape", shape)

    @classmethod
    def regular(cls, nx: int, ny: int, pitch: float, thickness: float) -> SensorGrid:
        """A rectangular grid of ``nx`` by ``ny`` sensors centred on the origin.

        Parameters
        ----------
        nx, ny : int
            Sensors along x and along y, each at least 1.
        pitch : float
            Distance between neighbouring sensors, metres.
        thickness : float
            Elastomer thickness, metres.
        """
        nx = _positive_count("nx", nx)
        ny = _positive_count("ny", ny)
        pitch = _positive_finite("pitch", pitch)
        thickness = _positive_finite("thickness", thickness)
        ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))  # x fastest in ravel order
        positions = np.column_stack(
            [(ix.ravel() - (nx - 1) / 2) * pitch, (iy.ravel() - (ny - 1) / 2) * pitch]
        )
        return cls(positions=positions, thickness=thickness, pitch=pitch, shape=(ny, nx))

    @property
    def size(self) -> int:
        """Number of sensors ``m``."""
        return self.positions.shape[0]

    @property
    def is_regular(self) -> bool:
        """True when the layout is a full ``(ny, nx)`` grid at spacing ``pitch``."""
        if len(self.shape) != 2:
            return False
        ny, nx = self.shape
        reference = SensorGrid.regular(nx, ny, self.pitch, self.thickness).positions
        offset = self.positions[0] - reference[0]
        return np.allclose(self.positions, reference + offset, rtol=0, atol=1e-9 * self.pitch)

    def with_thickness(self, thickness: float) -> SensorGrid:
        """The same layout under a layer of another thickness."""
        return SensorGrid(self.positions, thickness, self.pitch, self.shape)

    def __repr__(self) -> str:
        return (f"SensorGrid(shape={self.shape}, pitch={self.pitch:g} m, "
                f"thickness={self.thickness:g} m)")
