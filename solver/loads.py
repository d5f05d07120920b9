"""Simulated contacts with known truth, integrated finely and independently of the kernels.

A contact is a continuous surface traction: a normal pressure profile (Hertz,
cone, flat punch, uniform ellipse, ring) of a given total force, plus a
friction-like tangential traction ``shear_ratio * p`` in ``shear_direction``
and an optional torsion or squeeze. :func:`simulate` cuts the skin into sub-cells much
smaller than the layer thickness and integrates the traction over each
sub-cell (supersampled, so edges and clipped singularities are resolved). The
true nodal forces are the sub-cell forces summed over each node's cell. The
sensor stress comes from one of two media:

``medium="layer"`` (default)
    The skin as built: a layer of thickness ``h`` and the grid's Poisson ratio
    bonded to a rigid hull. The sub-cell tractions go through the layer's
    transfer functions (:func:`solver.layer.transfer`) by FFT convolution on
    the sub-cell lattice, and the stress is read at the sensors (averaged
    over the taxel through its transform when the grid has a
    ``sensor_size``). No Hankel table, no cell kernel: an independent path
    from the reconstruction's layer kernel.
``medium="halfspace"``
    The exact point-force stresses (Boussinesq and Cerruti) of every
    sub-cell summed at every sensor, the physics of the paper's kernels.

Neither step uses the reconstruction kernels' matrices.

Example
-------
>>> grid = SensorGrid.regular(16, 16, pitch=2e-3, thickness=2e-3)
>>> frame = simulate(grid, [hertz((0.3e-3, -1e-3), 5e-3, 1.0, shear_ratio=0.3)], noise=0.01, rng=0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from scipy import ndimage
from scipy.spatial import cKDTree

from . import layer
from .arrays import read_only
from .checks import one_of, whole_number
from .geometry import SensorGrid
from .kernels import half_space_point_stress, taxel_points

__all__ = [
    "ContactLoad", "SimulatedFrame", "hertz", "cone", "flat_punch", "ellipse", "ring",
    "simulate", "cell_forces", "SHAPES", "MEDIA",
]

SHAPES = ("hertz", "cone", "flat_punch", "ellipse", "ring")
MEDIA = ("layer", "halfspace")

# The layer's base stress has fallen below 3e-6 of its peak this many
# thicknesses from a load (any nu): the FFT lattice pads by it so that the
# periodic wrap-around stays below that level.
LAYER_REACH = 15.0


@dataclass(frozen=True)
class ContactLoad:
    """One continuous contact on the skin surface.

    Attributes
    ----------
    shape : str
        One of ``SHAPES``.
    center : (2,) tuple of float
        Contact centre on the surface, metres.
    semi_axes : (2,) tuple of float
        Contact radii along its own axes, metres (equal for round contacts;
        for ``ring`` the outer radius, with ``inner_radius`` below).
    force : float
        Total normal force, newtons (positive presses into the skin).
    shear_ratio : float
        Tangential over normal traction, everywhere in the contact.
    shear_direction : float
        Direction of the tangential traction, radians from +x.
    torsion : float
        Torque about the surface normal, newton metres (counter-clockwise
        positive), carried by a circumferential traction proportional to
        ``p(r) r``.
    squeeze : float
        Tangential over normal traction pushing the contact's two halves towards each other along
        ``squeeze_direction`` (negative: apart, a stretch): on either side of the line through the
        centre across that direction, ``squeeze * p`` towards the line. The halves' forces cancel;
        any shear adds to it.
    squeeze_direction : float
        The axis the halves are pushed along, radians from +x.
    angle : float
        Orientation of the first semi-axis, radians from +x.
    inner_radius : float
        Inner radius of a ``ring``, metres.
    clip : float
        Flat punch only: the edge singularity is clipped at ``(1 - clip)`` of
        the radius.
    """

    shape: str
    center: tuple
    semi_axes: tuple
    force: float
    shear_ratio: float = 0.0
    shear_direction: float = 0.0
    torsion: float = 0.0
    squeeze: float = 0.0
    squeeze_direction: float = 0.0
    angle: float = 0.0
    inner_radius: float = 0.0
    clip: float = 0.02

    def __post_init__(self):
        one_of("shape", self.shape, SHAPES)
        center = tuple(float(c) for c in self.center)
        axes = tuple(float(a) for a in self.semi_axes)
        if len(center) != 2 or not all(math.isfinite(c) for c in center):
            raise ValueError(f"center must be two finite coordinates in metres, got {self.center!r}")
        if len(axes) != 2 or not all(math.isfinite(a) and a > 0 for a in axes):
            raise ValueError(f"semi_axes must be two positive radii in metres, got {self.semi_axes!r}")
        for name in ("force", "shear_direction", "torsion", "squeeze", "squeeze_direction", "angle"):
            if not math.isfinite(float(getattr(self, name))):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        if not (math.isfinite(self.shear_ratio) and self.shear_ratio >= 0):
            raise ValueError(f"shear_ratio must be finite and >= 0, got {self.shear_ratio!r}")
        if self.shape == "ring" and not 0 <= self.inner_radius < min(axes):
            raise ValueError(
                f"inner_radius must be in [0, outer radius {min(axes)!r}), got {self.inner_radius!r}"
            )
        if not 0 < self.clip < 1:
            raise ValueError(f"clip must be in (0, 1), got {self.clip!r}")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "semi_axes", axes)

    @property
    def extent(self) -> float:
        """Radius of a circle holding the whole contact, metres."""
        return max(self.semi_axes)

    def profile(self, x, y):
        """Unnormalised normal pressure shape at surface points ``(x, y)``."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        dx, dy = x - self.center[0], y - self.center[1]
        u = (c * dx + s * dy) / self.semi_axes[0]
        v = (-s * dx + c * dy) / self.semi_axes[1]
        rho2 = u * u + v * v  # 1 on the contact edge
        inside = rho2 < 1.0
        p = np.zeros_like(rho2)
        if self.shape == "hertz":
            p[inside] = np.sqrt(1.0 - rho2[inside])
        elif self.shape == "cone":
            # Conical indenter: p ~ arccosh(a / r), log-singular at the tip.
            rho = np.sqrt(np.maximum(rho2[inside], 1e-12))
            p[inside] = np.arccosh(1.0 / rho)
        elif self.shape == "flat_punch":
            floor = 1.0 - (1.0 - self.clip) ** 2
            p[inside] = 1.0 / np.sqrt(np.maximum(1.0 - rho2[inside], floor))
        elif self.shape == "ellipse":
            p[inside] = 1.0
        else:  # ring
            inner = (self.inner_radius / self.semi_axes[0]) ** 2
            p[inside & (rho2 >= inner)] = 1.0
        return p


def _contact(shape, center, radius, force, **kw) -> ContactLoad:
    radius = float(radius) if np.ndim(radius) == 0 else radius
    axes = (radius, radius) if np.ndim(radius) == 0 else tuple(radius)
    return ContactLoad(shape, center, axes, force, **kw)


def hertz(center, radius, force, **kw) -> ContactLoad:
    """Hertzian contact ``p(r) = p0 sqrt(1 - r^2/a^2)`` of radius ``radius`` (m)."""
    return _contact("hertz", center, radius, force, **kw)


def cone(center, radius, force, **kw) -> ContactLoad:
    """Conical indenter, ``p(r) ~ arccosh(a/r)``."""
    return _contact("cone", center, radius, force, **kw)


def flat_punch(center, radius, force, *, clip=0.02, **kw) -> ContactLoad:
    """Rigid flat punch, ``p(r) ~ 1/sqrt(1 - r^2/a^2)``, edge clipped at ``(1-clip) a``."""
    return _contact("flat_punch", center, radius, force, clip=clip, **kw)


def ellipse(center, semi_axes, force, *, angle=0.0, **kw) -> ContactLoad:
    """Uniform pressure over an ellipse of semi-axes ``(a, b)`` (m) turned by ``angle``."""
    return ContactLoad("ellipse", center, tuple(semi_axes), force, angle=angle, **kw)


def ring(center, inner_radius, outer_radius, force, **kw) -> ContactLoad:
    """Uniform pressure over an annulus."""
    return ContactLoad("ring", center, (outer_radius, outer_radius), force,
                   inner_radius=inner_radius, **kw)


@dataclass(frozen=True)
class SimulatedFrame:
    """Sensor readings and the true nodal forces of simulated contacts.

    Attributes
    ----------
    grid : SensorGrid
    stress : (m,) ndarray
        ``T33`` at the sensors, pascals, compression positive, noise included.
    clean_stress : (m,) ndarray
        The same without noise.
    forces : (m, 3) ndarray
        True forces per node (Fx, Fy, Fz), newtons: the traction integrated over
        each node's cell. Load falling outside every cell is off the skin and
        counted nowhere.
    contacts : tuple of ContactLoad
    noise : float
        Standard deviation of the added noise relative to the peak clean stress.
    medium : str
        One of ``MEDIA``: the physics the stress was computed with.
    """

    grid: SensorGrid
    stress: np.ndarray
    clean_stress: np.ndarray
    forces: np.ndarray
    contacts: tuple = field(default_factory=tuple)
    noise: float = 0.0
    medium: str = "layer"


def cell_forces(contact: ContactLoad, x, y, step: float, supersample: int):
    """The contact's unnormalised normal force on square cells, by supersampling its profile.

    Parameters
    ----------
    contact : ContactLoad
    x, y : ndarray
        Cell centres, metres.
    step : float
        Cell side, metres.
    supersample : int
        Profile samples per cell along each axis.

    Returns
    -------
    ndarray
        The profile's mean over each cell times its area (shape of ``x``);
        scale by ``force / total`` to newtons.
    """
    offsets = ((np.arange(supersample) + 0.5) / supersample - 0.5) * step
    ox, oy = np.meshgrid(offsets, offsets)
    total = np.zeros_like(x)
    for sx, sy in zip(ox.ravel(), oy.ravel(), strict=True):
        total += contact.profile(x + sx, y + sy)
    return total / supersample**2 * step * step


def _normalisation(contact: ContactLoad, step, supersample, anchor):
    # Integrals of the profile over its whole support (on or off the skin),
    # on the skin's own sub-cell lattice (through ``anchor``), so clipped and
    # discretised shapes carry exactly the requested totals.
    axes = []
    for k in range(2):
        low = math.floor((contact.center[k] - contact.extent - anchor[k]) / step) - 1
        high = math.ceil((contact.center[k] + contact.extent - anchor[k]) / step) + 1
        axes.append(anchor[k] + (np.arange(low, high) + 0.5) * step)
    gx, gy = np.meshgrid(*axes)
    weights = cell_forces(contact, gx, gy, step, supersample)
    r2 = (gx - contact.center[0]) ** 2 + (gy - contact.center[1]) ** 2
    return weights.sum(), (weights * r2).sum()


def simulate(grid: SensorGrid, contacts, *, noise: float = 0.0, rng=None,
             subdivisions: int | None = None, supersample: int = 4,
             medium: str = "layer") -> SimulatedFrame:
    """Sensor stress and true nodal forces of one or several contacts.

    Parameters
    ----------
    grid : SensorGrid
    contacts : ContactLoad or sequence of ContactLoad
    noise : float, optional
        Gaussian sensor noise, standard deviation relative to the peak clean
        stress (``0.01`` is 1%). Default 0.
    rng : int or numpy.random.Generator, optional
        Seed or generator for the noise.
    subdivisions : int, optional
        Sub-cells per pitch along each axis. Default: enough that a sub-cell
        is at most a quarter of the thickness and a tenth of the smallest
        contact radius (at least 8, at most 128). Even numbers are rounded up
        to odd ones, so that sensors sit on the sub-cell lattice (and both
        media see the very same sub-cell forces).
    supersample : int, optional
        Profile samples per sub-cell along each axis. Default 4.
    medium : {"layer", "halfspace"}, optional
        The skin's physics (module notes). Default "layer", with the grid's
        Poisson ratio.

    Returns
    -------
    SimulatedFrame
    """
    if isinstance(contacts, ContactLoad):
        contacts = (contacts,)
    contacts = tuple(contacts)
    if not contacts or not all(isinstance(c, ContactLoad) for c in contacts):
        raise ValueError(f"contacts must be one or more ContactLoad, got {contacts!r}")
    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be finite and >= 0, got {noise!r}")
    one_of("medium", medium, MEDIA)
    pitch, h = grid.pitch, grid.thickness
    if subdivisions is None:
        smallest = min(min(c.semi_axes) for c in contacts)
        subdivisions = int(min(128, max(8, math.ceil(pitch / min(h / 4, smallest / 10)))))
    subdivisions = whole_number("subdivisions", subdivisions, low=1)
    if subdivisions % 2 == 0:
        subdivisions += 1   # odd: sensors of a regular grid sit on sub-cell centres
    step = pitch / subdivisions
    # Sub-cell centres tiling every node cell exactly.
    offsets = ((np.arange(subdivisions) + 0.5) / subdivisions - 0.5) * pitch
    ox, oy = np.meshgrid(offsets, offsets)
    tree = cKDTree(grid.positions)
    anchor = grid.positions[0] - pitch / 2  # a corner of the sub-cell lattice

    m = grid.size
    forces = np.zeros((m, 3))
    points = []   # loaded sub-cells of every contact: x, y, fx, fy, fz
    for contact in contacts:
        total, second_moment = _normalisation(contact, step, supersample, anchor)
        # node cells that the contact can touch
        near = tree.query_ball_point(contact.center, contact.extent + pitch)
        if not near:
            continue
        near = np.asarray(near)
        x = (grid.positions[near, 0, None] + ox.ravel()[None, :]).ravel()
        y = (grid.positions[near, 1, None] + oy.ravel()[None, :]).ravel()
        owner = np.repeat(near, subdivisions * subdivisions)
        fz = cell_forces(contact, x, y, step, supersample)
        loaded = fz > 0
        x, y, fz, owner = x[loaded], y[loaded], fz[loaded], owner[loaded]
        if fz.size == 0:
            continue
        # In irregular layouts cells may overlap: each sub-cell belongs to its nearest node only.
        keep = tree.query(np.column_stack([x, y]))[1] == owner
        x, y, fz, owner = x[keep], y[keep], fz[keep], owner[keep]
        fz = fz * (contact.force / total)
        dxc, dyc = x - contact.center[0], y - contact.center[1]
        fx = contact.shear_ratio * math.cos(contact.shear_direction) * fz
        fy = contact.shear_ratio * math.sin(contact.shear_direction) * fz
        if contact.torsion and second_moment > 0:
            # circumferential traction k p r: torque = k * integral p r^2 dA
            k = contact.torsion / (second_moment * contact.force / total)
            fx = fx - k * dyc * fz
            fy = fy + k * dxc * fz
        if contact.squeeze:
            ux, uy = math.cos(contact.squeeze_direction), math.sin(contact.squeeze_direction)
            towards = -contact.squeeze * np.sign(dxc * ux + dyc * uy) * fz  # along u, towards the line
            fx = fx + towards * ux
            fy = fy + towards * uy
        np.add.at(forces, (owner, 0), fx)
        np.add.at(forces, (owner, 1), fy)
        np.add.at(forces, (owner, 2), fz)
        points.append((x, y, fx, fy, fz))

    x, y, fx, fy, fz = (np.concatenate([p[k] for p in points]) if points else np.zeros(0)
                        for k in range(5))
    if medium == "layer":
        stress = _layer_stress(grid, x, y, fx, fy, fz, step)
    else:
        stress = _halfspace_stress(grid, x, y, fx, fy, fz)

    clean = stress.copy()
    if noise > 0:
        generator = np.random.default_rng(rng)
        stress = stress + generator.normal(0.0, noise * np.abs(clean).max(), size=m)
    return SimulatedFrame(grid=grid, stress=read_only(stress), clean_stress=read_only(clean),
                          forces=read_only(forces), contacts=contacts, noise=float(noise),
                          medium=medium)


def _halfspace_stress(grid: SensorGrid, x, y, fx, fy, fz):
    # Exact point-force stresses of every sub-cell, in chunks to bound memory.
    m = grid.size
    stress = np.zeros(m)
    offsets, weights = taxel_points(grid)
    chunk = max(1, 4_000_000 // m)
    for (ox, oy), weight in zip(offsets, weights, strict=True):
        sx, sy = grid.positions[:, 0, None] + ox, grid.positions[:, 1, None] + oy
        for start in range(0, x.size, chunk):
            sl = slice(start, start + chunk)
            kx, ky, kz = half_space_point_stress(sx - x[None, sl], sy - y[None, sl], grid.thickness)
            stress += weight * (kx @ fx[sl] + ky @ fy[sl] + kz @ fz[sl])
    return stress


def _layer_stress(grid: SensorGrid, x, y, fx, fy, fz, step):
    # FFT convolution of the sub-cell tractions with the layer's transfer
    # functions on the sub-cell lattice (anchored on the first sensor, so a
    # regular grid's sensors are lattice points), then read at the sensors.
    m, h = grid.size, grid.thickness
    stress = np.zeros(m)
    if x.size == 0:
        return stress
    anchor = grid.positions[0]
    reach = LAYER_REACH * h
    low = np.array([x.min(), y.min()]) - reach
    high = np.array([x.max(), y.max()]) + reach
    sensors = grid.positions
    near = np.flatnonzero(np.all((sensors >= low) & (sensors <= high), axis=1))
    if near.size == 0:
        return stress
    start = np.floor((np.minimum(low, sensors[near].min(axis=0)) - anchor) / step).astype(int) - 2
    stop = np.ceil((np.maximum(high, sensors[near].max(axis=0)) - anchor) / step).astype(int) + 2
    # the periodic lattice wraps: one more reach keeps the images apart
    size = [scipy.fft.next_fast_len(int(n), real=True) for n in (stop - start + 1 + int(reach / step))]
    origin = anchor + start * step
    # Cloud-in-cell deposit: exact for sub-cells on the lattice, and it keeps
    # the total force and first moment of any others.
    grids = [np.zeros(size[::-1]) for _ in range(3)]
    gx, gy = (x - origin[0]) / step, (y - origin[1]) / step
    ix, iy = np.floor(gx).astype(int), np.floor(gy).astype(int)
    wx, wy = gx - ix, gy - iy
    for image, values in zip(grids, (fx, fy, fz), strict=True):
        for dx_, wxs in ((0, 1 - wx), (1, wx)):
            for dy_, wys in ((0, 1 - wy), (1, wy)):
                np.add.at(image, (iy + dy_, ix + dx_), values * wxs * wys)
    kx = 2 * np.pi * scipy.fft.rfftfreq(size[0], step)
    ky = 2 * np.pi * scipy.fft.fftfreq(size[1], step)
    kxx, kyy = np.meshgrid(kx, ky)
    k = np.hypot(kxx, kyy)
    # transfer functions on a fine 1-D table of kh, linear interpolation (error < 1e-5)
    table_kh, normal, tangential = layer.transfer_table(grid.poisson_ratio)
    g_n = np.interp(k * h, table_kh, normal, right=0.0)
    g_t = np.interp(k * h, table_kh, tangential, right=0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        direction_x = np.where(k > 0, kxx / k, 0.0)
        direction_y = np.where(k > 0, kyy / k, 0.0)
    # each sub-cell's force spread over its square; sensors averaged over their taxel
    window = np.sinc(kxx * step / (2 * np.pi)) * np.sinc(kyy * step / (2 * np.pi))
    if grid.sensor_size > 0:
        side = grid.sensor_size
        window = window * np.sinc(kxx * side / (2 * np.pi)) * np.sinc(kyy * side / (2 * np.pi))
    fx_hat, fy_hat, fz_hat = (scipy.fft.rfft2(image) for image in grids)
    response = (g_n * fz_hat - 1j * g_t * (direction_x * fx_hat + direction_y * fy_hat)) * window
    field = scipy.fft.irfft2(response, s=size[::-1]) / (step * step)
    # spline read-out: exact at lattice points, smooth (kernel scale h >> step) elsewhere
    coords = (sensors[near] - origin) / step
    stress[near] = ndimage.map_coordinates(field, [coords[:, 1], coords[:, 0]], order=3, mode="wrap")
    return stress
