"""Forward model: normal stress at the sensors from surface forces at the nodes.

Two kernels give the stress ``T33`` at depth ``h`` (compression positive)
produced by a unit force on a node:

``point``
    The force concentrated at the node (Boussinesq normal load plus Cerruti
    tangential load on an elastic half-space; exact for this stress component
    whatever Poisson's ratio).
``cell``
    The force spread uniformly over the node's ``pitch x pitch`` cell, in
    closed form (Love's rectangle for the normal part, the integrated Cerruti
    term for the tangential part). This keeps the sum over the grid right when
    ``h`` is not much larger than the pitch, where the point kernel loses
    much of the total force.

The stress matrix is ``C = [Cx | Cy | Cz]`` of shape ``(m, 3m)`` so that
``b = C @ concatenate([Fx, Fy, Fz])``.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .geometry import SensorGrid

__all__ = ["KERNELS", "point_force_stress", "cell_force_stress", "stress_matrix"]

KERNELS = ("cell", "point")


def point_force_stress(dx, dy, depth):
    """Stress ``T33`` at ``depth`` per newton of a point force.

    Parameters
    ----------
    dx, dy : ndarray
        Sensor position minus load position, metres (broadcast together).
    depth : float
        Sensor depth ``h``, metres.

    Returns
    -------
    kx, ky, kz : ndarray
        Pascals per newton of force along x, y and z (z into the skin).
    """
    # T33 = 3 h^2 (dx Fx + dy Fy + h Fz) / (2 pi R^5)
    r2 = dx * dx + dy * dy + depth * depth
    common = 3.0 * depth * depth / (2.0 * np.pi * r2 * r2 * np.sqrt(r2))
    return common * dx, common * dy, common * depth


def _love_corner(a, b, depth):
    # Uniform unit pressure on the rectangle [0, a] x [0, b] (signed sides),
    # stress below the corner at the origin; odd in a and in b, so signed
    # sums over four corners give any rectangle.
    z2 = depth * depth
    r1 = a * a + z2
    r2 = b * b + z2
    r3 = np.sqrt(a * a + b * b + z2)
    return (np.arctan(a * b / (depth * r3)) + a * b * depth / r3 * (1.0 / r1 + 1.0 / r2)) / (2.0 * np.pi)


def _cerruti_strip(a, t, depth):
    # Antiderivative in t of the x-integrated Cerruti term: J(a) in DESIGN.md.
    s = a * a + depth * depth
    return t / (s * np.sqrt(t * t + s))


def cell_force_stress(dx, dy, depth, width):
    """Stress ``T33`` per newton spread uniformly over a square cell.

    Parameters
    ----------
    dx, dy : ndarray
        Sensor position minus cell centre, metres (broadcast together).
    depth : float
        Sensor depth ``h``, metres.
    width : float
        Side of the square cell, metres.

    Returns
    -------
    kx, ky, kz : ndarray
        Pascals per newton of force along x, y and z.
    """
    half = 0.5 * width
    q = 1.0 / (width * width)  # traction of one newton over the cell
    # load sides relative to the sensor: [a1, a2] x [b1, b2]
    a1, a2 = -dx - half, -dx + half
    b1, b2 = -dy - half, -dy + half
    kz = q * (_love_corner(a2, b2, depth) - _love_corner(a1, b2, depth)
              - _love_corner(a2, b1, depth) + _love_corner(a1, b1, depth))
    # Cerruti along x: q h^2/(2 pi) [J(x - u2) - J(x - u1)] between t = b1 and b2,
    # where x - u2 = -a2 and J is even in its first argument.
    scale = q * depth * depth / (2.0 * np.pi)
    kx = scale * ((_cerruti_strip(a2, b2, depth) - _cerruti_strip(a2, b1, depth))
                  - (_cerruti_strip(a1, b2, depth) - _cerruti_strip(a1, b1, depth)))
    ky = scale * ((_cerruti_strip(b2, a2, depth) - _cerruti_strip(b2, a1, depth))
                  - (_cerruti_strip(b1, a2, depth) - _cerruti_strip(b1, a1, depth)))
    return kx, ky, kz


def _spread_offsets(values, out):
    # values[u, v] holds the kernel for sensor - node = (v - nx + 1, u - ny + 1)
    # pitches; spread it into the (m, m) block-Toeplitz block ``out`` (a view)
    # with a single copy and no recomputation.
    ny, nx = (values.shape[0] + 1) // 2, (values.shape[1] + 1) // 2
    windows = sliding_window_view(values[::-1, ::-1], (ny, nx))[::-1, ::-1]
    np.copyto(out.reshape(ny, nx, ny, nx), windows)


def stress_matrix(grid: SensorGrid, kernel: str = "cell") -> np.ndarray:
    """The forward matrix ``C = [Cx | Cy | Cz]`` of a sensor grid.

    Parameters
    ----------
    grid : SensorGrid
        Sensor layout; nodes coincide with sensors.
    kernel : {"cell", "point"}
        How a node's force is spread on the surface (see module notes).

    Returns
    -------
    C : (m, 3m) ndarray
        Pascals per newton; ``C[i, j]`` is the stress at sensor ``i`` from a
        unit force component on node ``j mod m``.
    """
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    h, pitch = grid.thickness, grid.pitch

    def evaluate(dx, dy):
        if kernel == "point":
            return point_force_stress(dx, dy, h)
        return cell_force_stress(dx, dy, h, pitch)

    m = grid.size
    matrix = np.empty((m, 3 * m))
    if grid.is_regular:
        # Translation invariance: evaluate on the (2ny-1, 2nx-1) offsets once.
        ny, nx = grid.shape
        oy, ox = np.meshgrid(np.arange(-(ny - 1), ny) * pitch, np.arange(-(nx - 1), nx) * pitch,
                             indexing="ij")
        for i, values in enumerate(evaluate(ox, oy)):
            _spread_offsets(values, matrix[:, i * m:(i + 1) * m])
    else:
        p = grid.positions
        dx = p[:, 0, None] - p[None, :, 0]
        dy = p[:, 1, None] - p[None, :, 1]
        for i, block in enumerate(evaluate(dx, dy)):
            matrix[:, i * m:(i + 1) * m] = block
    return matrix
