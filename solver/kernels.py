"""Forward model: normal stress at the sensors from surface forces at the nodes.

Three kernels give the stress ``T33`` at depth ``h`` (compression positive)
produced by a unit force on a node:

``layer`` (default)
    What a skin is: an elastomer layer of thickness ``h`` and Poisson ratio
    ``nu`` bonded to a rigid hull, the sensors on the hull, each node's force
    spread uniformly over its cell (exact layer solution,
    :mod:`solver.layer`). Unlike the half-space it depends on ``nu``; its
    base stress peaks higher and narrower and decays exponentially.
``point``
    The force concentrated at the node (Boussinesq normal load plus Cerruti
    tangential load on an elastic half-space; exact for this stress component
    whatever Poisson's ratio).
``cell``
    The half-space with the force spread uniformly over the node's ``pitch x pitch`` cell, in
    closed form (Love's rectangle for the normal part, the integrated Cerruti
    term for the tangential part). This keeps the sum over the grid right when
    ``h`` is not much larger than the pitch, where the point kernel loses
    much of the total force.

The first two are the paper's half-space kernels, kept for comparison. A
grid with a ``sensor_size`` averages every kernel over its square taxels
(Gauss-Legendre points on the taxel) instead of reading it at a point.

The stress matrix is ``C = [Cx | Cy | Cz]`` of shape ``(m, 3m)`` so that
``b = C @ concatenate([Fx, Fy, Fz])``.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from . import layer
from .checks import one_of, whole_number
from .geometry import SensorGrid, check_poisson_ratio

__all__ = ["KERNELS", "offset_tables", "half_space_point_stress", "cell_force_stress", "layer_force_stress",
           "taxel_points", "subcell_offsets", "stress_matrix", "PROFILES"]

KERNELS = ("layer", "cell", "point")
PROFILES = ("uniform", "bilinear")


def half_space_point_stress(dx, dy, depth):
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


def _panels(length: float, thickness: float):
    # Gauss-Legendre nodes and weights on [0, 1] in panels no longer than
    # layer.EDGE_PANEL thicknesses: the integrands vary on the scale of h.
    count = int(min(256, max(1, math.ceil(length / (layer.EDGE_PANEL * thickness)))))
    nodes, weights = np.polynomial.legendre.leggauss(8)
    edges = np.linspace(0.0, 1.0, count + 1)
    mid, half = (edges[:-1] + edges[1:]) / 2, np.diff(edges) / 2
    return (mid[:, None] + half[:, None] * nodes).ravel(), (half[:, None] * weights).ravel()


def layer_force_stress(dx, dy, thickness: float, width: float, poisson_ratio: float):
    """``T33`` on the base of a bonded layer per newton spread uniformly over a square cell.

    By the divergence theorem the cell integral of the layer's point kernel
    is a sum of line integrals over the cell's edges of the smooth tabulated
    functions of :class:`solver.layer.LayerTable` (Gauss-Legendre panels of
    at most ``EDGE_PANEL`` thicknesses), so thin layers need no special case.

    Parameters
    ----------
    dx, dy : ndarray
        Sensor position minus cell centre, metres (broadcast together).
    thickness : float
        Layer thickness ``h``, metres.
    width : float
        Side of the square cell, metres.
    poisson_ratio : float
        ``nu`` in [0, 0.5].

    Returns
    -------
    kx, ky, kz : ndarray
        Pascals per newton of force along x, y and z (z into the skin).
    """
    tab = layer.table(check_poisson_ratio(poisson_ratio))
    dx, dy = np.broadcast_arrays(np.asarray(dx, float), np.asarray(dy, float))
    shape = dx.shape
    dx, dy = dx.ravel(), dy.ravel()
    half, h = 0.5 * width, thickness
    kx, ky, kz = (np.zeros(dx.size) for _ in range(3))
    # Sensors farther than the tables reach from the cell feel nothing.
    gap = np.hypot(np.maximum(np.abs(dx) - half, 0.0), np.maximum(np.abs(dy) - half, 0.0))
    near = np.flatnonzero(gap < tab.reach * h)
    nodes, weights = _panels(width, h)
    t = nodes - 0.5                                   # along an edge, in widths, from its middle
    q = 1.0 / (width * width)                         # traction of one newton over the cell

    def along(fixed, centre, function):
        # int over the edge {fixed} x [centre - width/2, centre + width/2] of function(rho / h) dt
        run = centre[:, None] + t[None, :] * width
        rho = np.hypot(fixed[:, None], run) / h
        return function(rho) @ weights * width

    def flux(fixed, centre):
        # normal: int_cell K = sum over edges of int (rho . n) F(rho) / (2 pi rho^2) dl
        return fixed * along(fixed, centre, tab.carried) / (2.0 * np.pi * h * h)

    # in blocks that keep the (pairs, nodes) work arrays near 16 MB
    block = max(1, 2_000_000 // t.size)
    for start in range(0, near.size, block):
        rows = near[start:start + block]
        a1, a2 = -dx[rows] - half, -dx[rows] + half   # load cell relative to the sensor
        b1, b2 = -dy[rows] - half, -dy[rows] + half
        mid_a, mid_b = -dx[rows], -dy[rows]
        kz[rows] = q * (flux(a2, mid_b) - flux(a1, mid_b) + flux(b2, mid_a) - flux(b1, mid_a))
        # Tangential: T33 = d/dx_sensor Psi(|x - s|) integrated over s_x leaves the two
        # edges across x: int [Psi(left edge) - Psi(right edge)] dt (and alike for y).
        kx[rows] = q * (along(a1, mid_b, tab.tangential_potential)
                        - along(a2, mid_b, tab.tangential_potential)) / h
        ky[rows] = q * (along(b1, mid_a, tab.tangential_potential)
                        - along(b2, mid_a, tab.tangential_potential)) / h
    return kx.reshape(shape), ky.reshape(shape), kz.reshape(shape)


def _spread_offsets(values, out):
    # values[u, v] holds the kernel for sensor - node = (v - nx + 1, u - ny + 1)
    # pitches; spread it into the (m, m) block-Toeplitz block ``out`` (a view,
    # stored by column) with a single copy and no recomputation.
    ny, nx = (values.shape[0] + 1) // 2, (values.shape[1] + 1) // 2
    windows = sliding_window_view(values[::-1, ::-1], (ny, nx))[::-1, ::-1]
    by_node = out.T.view()
    by_node.shape = (ny, nx, ny, nx)  # raises rather than reshaping a copy
    np.copyto(by_node, windows.transpose(2, 3, 0, 1))


def taxel_points(grid: SensorGrid):
    """Where a reading is taken over the taxel, and with what weight.

    Returns
    -------
    offsets : (k, 2) ndarray
        Gauss-Legendre points on the square taxel relative to its centre,
        metres (the centre alone for point sensors).
    weights : (k,) ndarray
        Their weights, summing to 1.
    """
    if grid.sensor_size == 0:
        return np.zeros((1, 2)), np.ones(1)
    # the kernels vary on the scale of h: about three points per thickness
    return _square_points(grid.sensor_size, int(min(12, max(2, math.ceil(3.0 * grid.sensor_size
                                                                          / grid.thickness)))))


def _square_points(size, count):
    # count x count Gauss-Legendre points on a size x size square about its centre, and their
    # weights (summing to 1)
    nodes, weights = np.polynomial.legendre.leggauss(count)
    u, v = np.meshgrid(0.5 * size * nodes, 0.5 * size * nodes)
    return np.column_stack([u.ravel(), v.ravel()]), np.outer(weights, weights).ravel() / 4.0


def subcell_offsets(pitch: float, subdivision: int) -> np.ndarray:
    """Where the sub-cells of :func:`stress_matrix` sit in their node's cell.

    Parameters
    ----------
    pitch : float
        Node spacing, metres.
    subdivision : int
        Sub-cells per pitch along each axis.

    Returns
    -------
    (subdivision**2, 2) ndarray
        Row ``q``: sub-cell ``q``'s centre ``(x, y)`` from the node, metres
        (row-major within the cell, x fastest, as the matrix's columns).
    """
    centres = (np.arange(subdivision) + 0.5) * (pitch / subdivision) - 0.5 * pitch
    q = np.arange(subdivision * subdivision)
    return np.column_stack([centres[q % subdivision], centres[q // subdivision]])


def _evaluator(grid, kernel, width):
    # (dx, dy, points, weights) -> (kx, ky, kz): the kernel of a uniform width x width source
    # averaged over sample points (a taxel's, and a hat's shifts) with their weights
    h = grid.thickness

    def at_point(dx, dy):
        if kernel == "point":
            return half_space_point_stress(dx, dy, h)
        if kernel == "cell":
            return cell_force_stress(dx, dy, h, width)
        return layer_force_stress(dx, dy, h, width, grid.poisson_ratio)

    def evaluate(dx, dy, points, weights):
        if points.shape[0] == 1 and not points.any():
            return at_point(dx, dy)
        total = [np.zeros(np.shape(dx)) for _ in range(3)]
        for (u, v), weight in zip(points, weights, strict=True):
            for acc, part in zip(total, at_point(dx + u, dy + v), strict=True):
                acc += weight * part
        return total
    return evaluate


# Offset tables of recent geometries, the largest grid computed so far for each: a region
# solver's windows are sub-grids of one skin, so a window's tables are the centre of a larger
# window's (a hat costs its kernel at 9 to 64 shifts).
# At most _TABLES_KEPT geometries and _TABLES_BYTES of tables; the latest is always kept (a 256x256
# skin's tables at subdivision 4 are about 100 MB).
_TABLES: OrderedDict = OrderedDict()
_TABLES_KEPT = 8  # one round of the trade-off tool's configurations uses 5
_TABLES_BYTES = 256 * 2**20
_TABLES_LOCK = threading.Lock()
_BUILDING: dict = {}  # a lock per geometry whose tables are being computed, held meanwhile


def offset_tables(grid, kernel, subdivision, profile):
    """The kernel of a regular grid on every offset, sensor minus node.

    Every kernel depends only on the offset, so these tables are the whole
    matrix: :func:`stress_matrix` reads its columns from them, and
    :mod:`solver.convolution` convolves with them. Kept per geometry (the
    largest grid asked so far; a smaller one reads its middle).

    Parameters
    ----------
    grid : SensorGrid
        A regular grid, ``grid.shape == (ny, nx)``.
    kernel : {"layer", "cell", "point"}
    subdivision : int
        Sub-cells per side of a cell (:func:`stress_matrix`).
    profile : {"uniform", "bilinear"}
        How a sub-cell's force is spread (:func:`stress_matrix`).

    Returns
    -------
    list of [kx, ky, kz]
        Per sub-cell ``q``, the stress per newton along x, y, z of its source:
        ``(2 ny - 1, 2 nx - 1)`` arrays, offset (0, 0) at index ``(ny - 1, nx - 1)``,
        pascals per newton. Shared: not to be written.
    """
    ny, nx = grid.shape
    hats = subdivision > 1 and profile == "bilinear"
    key = (kernel, grid.pitch, grid.thickness, grid.poisson_ratio, grid.sensor_size, subdivision, hats)
    kept = _kept(key)
    if kept is None or kept[0] < ny or kept[1] < nx:
        # one thread computes a geometry's tables; another that needs them meanwhile waits for
        # them instead of computing them too (seconds of CPU and the memory twice)
        with _TABLES_LOCK:
            building = _BUILDING.setdefault(key, threading.Lock())
        with building:
            kept = _kept(key)
            if kept is None or kept[0] < ny or kept[1] < nx:
                size = (ny, nx) if kept is None else (max(ny, kept[0]), max(nx, kept[1]))
                kept = (*size, _compute_tables(grid, kernel, subdivision, hats, *size))
                with _TABLES_LOCK:
                    _TABLES[key] = kept
                    _TABLES.move_to_end(key)
                    total = sum(map(_table_bytes, _TABLES.values()))
                    while len(_TABLES) > 1 and (len(_TABLES) > _TABLES_KEPT or total > _TABLES_BYTES):
                        total -= _table_bytes(_TABLES.popitem(last=False)[1])
                    # stored: a thread asking later finds the tables (a waiting one holds this lock)
                    _BUILDING.pop(key, None)
    big_y, big_x, tables = kept
    rows, columns = slice(big_y - ny, big_y + ny - 1), slice(big_x - nx, big_x + nx - 1)
    return [[table[rows, columns] for table in parts] for parts in tables]


def _kept(key):
    # the kept tables of a geometry, now the most recently used; None if there are none
    with _TABLES_LOCK:
        kept = _TABLES.get(key)
        if kept is not None:
            _TABLES.move_to_end(key)
        return kept


def _table_bytes(entry):
    return sum(table.nbytes for parts in entry[2] for table in parts)


def _compute_tables(grid, kernel, subdivision, hats, ny, nx):
    pitch, h = grid.pitch, grid.thickness
    width = pitch / subdivision
    evaluate = _evaluator(grid, kernel, width)
    taxel = taxel_points(grid)
    smeared = taxel
    if hats:
        # The hat of half-width w is the uniform w x w square smeared uniformly over a w x w
        # square of shifts (a triangle is a box convolved with a box), so its kernel is the
        # sub-cell kernel averaged over those shifts: Gauss-Legendre points, more when h is
        # small against w (within 0.1% of a fine integration of the hat down to h = w / 2,
        # the thinnest layer the contact fit gives sub-cells; at most 8 per axis).
        shifts, shift_weights = _square_points(width, int(min(8, max(3, math.ceil(4.0 * width / h)))))
        smeared = ((taxel[0][:, None, :] + shifts[None, :, :]).reshape(-1, 2),
                   np.outer(taxel[1], shift_weights).ravel())
    oy, ox = np.meshgrid(np.arange(-(ny - 1), ny) * pitch, np.arange(-(nx - 1), nx) * pitch, indexing="ij")
    # Every kernel is odd in the offset along its force and even across it, and the sub-cells
    # lie mirrored about the node: those right of (above) the node read the tables of their
    # mirror images reversed along x (y), the x (y) component negated. The offsets are
    # symmetric, so only the lower-left quarter of the sub-cells is evaluated. (By index: a
    # middle sub-cell's centre may round to a hair off zero.)
    lower = {}
    for q, (cx, cy) in enumerate(subcell_offsets(pitch, subdivision)):
        if 2 * (q % subdivision) < subdivision and 2 * (q // subdivision) < subdivision:
            lower[q] = evaluate(ox - cx, oy - cy, *smeared)
    tables = []
    for q in range(subdivision * subdivision):
        column, row = q % subdivision, q // subdivision
        mirror = min(column, subdivision - 1 - column) + subdivision * min(row, subdivision - 1 - row)
        kx, ky, kz = lower[mirror]
        if 2 * column >= subdivision:
            kx, ky, kz = -kx[:, ::-1], ky[:, ::-1], kz[:, ::-1]
        if 2 * row >= subdivision:
            kx, ky, kz = kx[::-1], -ky[::-1], kz[::-1]
        tables.append([np.ascontiguousarray(part) for part in (kx, ky, kz)])
        for table in tables[-1]:
            table.setflags(write=False)  # shared by every grid of this geometry
    return tables


def stress_matrix(grid: SensorGrid, kernel: str = "layer", *, subdivision: int = 1,
                  profile: str = "uniform") -> np.ndarray:
    """The forward matrix ``C = [Cx | Cy | Cz]`` of a sensor grid.

    Parameters
    ----------
    grid : SensorGrid
        Sensor layout; nodes coincide with sensors.
    kernel : {"layer", "cell", "point"}
        The medium and how a node's force is spread on the surface (see
        module notes). Default "layer".

    subdivision : int, optional
        ``s``: split every cell into ``s x s`` sub-cells, each its own source
        (the contact fit's finer load profile). Default 1. Not defined for
        the point kernel, and only on regular grids when ``s > 1``.
    profile : {"uniform", "bilinear"}, optional
        How a sub-cell's force is spread when ``s > 1``: uniformly over the
        sub-cell (default), or as the bilinear hat centred on it that reaches
        the neighbouring sub-cells' centres (half-width ``pitch / s``). Hats on
        the sub-cell lattice add up to a continuous, piecewise bilinear load,
        so a smooth contact is no staircase of sub-cells; a hat's force acts
        at its centre, like the uniform sub-cell's; on the skin's border nodes
        it reaches half a sub-cell past the last cell. Ignored when ``s = 1``.

    Returns
    -------
    C : (m, 3 m s^2) ndarray
        Stored by column (Fortran order: a node's column is contiguous, as
        the contact fit and the exact member read them). Pascals per newton;
        ``C[i, c * m s^2 + q * m + j]`` is the stress at sensor ``i`` from a
        unit force component ``c`` (x, y, z) on sub-cell ``q`` (row-major
        within the cell, x fastest) of node ``j``. With ``s = 1``,
        ``C[i, j]`` is the stress from a unit force component on node
        ``j mod m``.
    """
    one_of("kernel", kernel, KERNELS)
    subdivision = whole_number("subdivision", subdivision, low=1)
    one_of("profile", profile, PROFILES)
    if subdivision > 1 and (kernel == "point" or not grid.is_regular):
        raise ValueError("subdivision > 1 needs a regular grid and a cell or layer kernel, got "
                         f"{'an irregular grid' if not grid.is_regular else 'the point kernel'}")
    m = grid.size
    cells = subdivision * subdivision
    matrix = np.empty((3 * m * cells, m)).T
    if grid.is_regular:
        # Translation invariance: the kernel on the (2ny-1, 2nx-1) offsets, once per sub-cell.
        ny, nx = grid.shape
        for q, parts in enumerate(offset_tables(grid, kernel, subdivision, profile)):
            for i, values in enumerate(parts):
                start = (i * cells + q) * m
                _spread_offsets(values, matrix[:, start:start + m])
    else:
        p = grid.positions
        dx = p[:, 0, None] - p[None, :, 0]
        dy = p[:, 1, None] - p[None, :, 1]
        for i, block in enumerate(_evaluator(grid, kernel, grid.pitch)(dx, dy, *taxel_points(grid))):
            matrix[:, i * m:(i + 1) * m] = block
    return matrix
