"""Sensor layouts: where the taxels are, how thick and compressible the elastomer, how big a taxel."""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from .arrays import read_only
from .checks import real, shown

__all__ = ["SensorGrid", "check_poisson_ratio", "patch_links", "neighbours_within"]


def _positive_finite(name: str, value) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number of metres, got {value!r}") from None
    if not math.isfinite(number) or number <= 0.0:
        raise ValueError(f"{name} must be a positive finite number of metres, got {value!r}")
    return number


def check_poisson_ratio(value) -> float:
    """``value`` as a Poisson ratio in [0, 0.5]; ValueError naming ``poisson_ratio`` otherwise."""
    # an isotropic solid has -1 < nu <= 0.5; elastomers are not auxetic, and 0.5 itself
    # (incompressible) must stay allowed because real silicones are within 1e-3 of it
    number = real(value)
    if number is None or not math.isfinite(number) or not 0.0 <= number <= 0.5:
        raise ValueError(f"poisson_ratio must be a finite number in [0, 0.5], got {shown(value)}")
    return number


def _sensor_size(value, pitch: float) -> float:
    number = real(value)
    if number is None or not math.isfinite(number) or number < 0.0:
        raise ValueError("sensor_size must be a finite number of metres >= 0 (0 for point sensors), "
                         f"got {shown(value)}")
    if number > pitch:
        raise ValueError(f"sensor_size must be at most the pitch (taxels cannot overlap), got "
                         f"{number:g} m with pitch {pitch:g} m")
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

    Nodes (where forces are reconstructed) coincide with the sensors. The
    elastomer's Poisson ratio and the taxels' size belong to the geometry
    because the forward model of a layer bonded to a rigid hull depends on
    them (a half-space's normal stress ``T33`` does not depend on ``nu``).

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
    poisson_ratio : float
        Poisson ratio ``nu`` of the elastomer, dimensionless, in ``[0, 0.5]``;
        0.5 (the default) is incompressible, which silicone rubbers nearly are.
    sensor_size : float
        Side of the square taxel over which each reading is averaged, metres,
        in ``[0, pitch]`` (taxels cannot overlap); 0 (the default) means point
        sensors.

    Raises
    ------
    ValueError
        When a field is impossible; the message names the field, the rule and
        the value received.
    """

    positions: np.ndarray
    thickness: float
    pitch: float
    shape: tuple
    poisson_ratio: float = 0.5
    sensor_size: float = 0.0

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
        object.__setattr__(self, "poisson_ratio", check_poisson_ratio(self.poisson_ratio))
        object.__setattr__(self, "sensor_size", _sensor_size(self.sensor_size, self.pitch))
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
    def regular(cls, nx: int, ny: int, pitch: float, thickness: float, *, poisson_ratio: float = 0.5,
                sensor_size: float = 0.0) -> SensorGrid:
        """A rectangular grid of ``nx`` by ``ny`` sensors centred on the origin.

        Parameters
        ----------
        nx, ny : int
            Sensors along x and along y, each at least 1.
        pitch : float
            Distance between neighbouring sensors, metres.
        thickness : float
            Elastomer thickness, metres.
        poisson_ratio : float, optional
            Poisson ratio ``nu`` of the elastomer, in ``[0, 0.5]``; default 0.5
            (incompressible).
        sensor_size : float, optional
            Side of the square taxel, metres, in ``[0, pitch]``; default 0
            (point sensors).

        Returns
        -------
        SensorGrid
            Row-major with x fastest, ``shape == (ny, nx)``.
        """
        nx = _positive_count("nx", nx)
        ny = _positive_count("ny", ny)
        pitch = _positive_finite("pitch", pitch)
        thickness = _positive_finite("thickness", thickness)
        ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))  # x fastest in ravel order
        positions = np.column_stack(
            [(ix.ravel() - (nx - 1) / 2) * pitch, (iy.ravel() - (ny - 1) / 2) * pitch]
        )
        return cls(positions=positions, thickness=thickness, pitch=pitch, shape=(ny, nx),
                   poisson_ratio=poisson_ratio, sensor_size=sensor_size)

    @property
    def size(self) -> int:
        """Number of sensors ``m``."""
        return self.positions.shape[0]

    @functools.cached_property
    def is_regular(self) -> bool:
        """True when the layout is a full ``(ny, nx)`` grid at spacing ``pitch``."""
        if len(self.shape) != 2:
            return False
        ny, nx = self.shape
        reference = SensorGrid.regular(nx, ny, self.pitch, self.thickness).positions
        offset = self.positions[0] - reference[0]
        return np.allclose(self.positions, reference + offset, rtol=0, atol=1e-9 * self.pitch)

    @functools.cached_property
    def border(self) -> np.ndarray:
        """(m,) ndarray of bool, read-only: the nodes of a regular grid's outer rows and columns,
        where a contact's stress field is partly off the skin (none on other layouts)."""
        edge = np.zeros(self.shape if self.is_regular else self.size, dtype=bool)
        if self.is_regular:
            edge[[0, -1], :] = edge[:, [0, -1]] = True
        edge = edge.ravel()
        edge.setflags(write=False)
        return edge

    @property
    def key(self) -> tuple:
        """Everything a solver for this grid depends on, hashable: two grids with equal keys
        share their stress matrices (shape, pitch, thickness, Poisson ratio, taxel size, positions)."""
        return (self.shape, self.pitch, self.thickness, self.poisson_ratio, self.sensor_size,
                self.positions.tobytes())

    def with_thickness(self, thickness: float) -> SensorGrid:
        """The same layout, elastomer and taxels under a layer of another thickness (metres)."""
        return self.replace(thickness=thickness)

    def replace(self, **changes) -> SensorGrid:
        """A copy with some fields changed, checked like a new grid; the rest (``nu`` too) is kept.

        Parameters
        ----------
        **changes
            New values of any of ``positions``, ``thickness``, ``pitch``,
            ``shape``, ``poisson_ratio``, ``sensor_size``.

        Returns
        -------
        SensorGrid

        Examples
        --------
        A window of a larger skin keeps its material:

        >>> skin = SensorGrid.regular(8, 8, 2e-3, 2e-3, poisson_ratio=0.45)
        >>> window = skin.replace(positions=skin.positions[:4], shape=(4,))
        >>> window.poisson_ratio
        0.45
        """
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        taxel = f", sensor_size={self.sensor_size:g} m" if self.sensor_size > 0 else ""
        return (f"SensorGrid(shape={self.shape}, pitch={self.pitch:g} m, "
                f"thickness={self.thickness:g} m, nu={self.poisson_ratio:g}{taxel})")


def patch_links(grid: SensorGrid, tree: cKDTree | None = None):
    """``(indptr, indices)`` of the CSR matrix linking the nodes of one patch: those within
    1.5 pitches (the 8 neighbours on a grid), as :func:`solver.search.contact_cores` takes it."""
    return neighbours_within(cKDTree(grid.positions) if tree is None else tree, 1.5 * grid.pitch)


def neighbours_within(tree: cKDTree, distance: float):
    """``(indptr, indices)`` (int64, as the compiled code takes them) of the CSR matrix linking
    the nodes of ``tree`` closer than ``distance`` metres, each node to itself too."""
    pairs = tree.sparse_distance_matrix(tree, distance, output_type="coo_matrix").tocsr()
    linked = (pairs + sparse.identity(tree.n, format="csr")).astype(bool).astype(np.int8)
    return linked.indptr.astype(np.int64), linked.indices.astype(np.int64)
