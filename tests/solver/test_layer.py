"""The bonded layer: transfer functions, tables, and the layer kernel against independent paths."""

import math

import numpy as np
import pytest
import scipy.linalg
from scipy.special import j0, j1

from solver import kernels, layer, loads
from solver.geometry import SensorGrid

NUS = [0.0, 0.3, 0.45, 0.5]


def gauss_panels(top, panel, order=8):
    # composite Gauss-Legendre nodes and weights on [0, top]
    nodes, weights = np.polynomial.legendre.leggauss(order)
    edges = np.arange(0.0, top + 1e-12, panel)
    mid, half = (edges[:-1] + edges[1:]) / 2, np.diff(edges) / 2
    return (mid[:, None] + half[:, None] * nodes).ravel(), (half[:, None] * weights).ravel()


# -- transfer functions ---------------------------------------------------------------


@pytest.mark.parametrize("nu", NUS)
def test_deep_inside_a_thick_layer_the_transfer_is_the_half_space_one(nu):
    # read at depth z = H / 500: the base is too far to matter (its echo is ~e^{-2 k H})
    kz = np.linspace(0.1, 30.0, 300)
    normal, tangential = layer.transfer(500.0 * kz, nu, depth=1.0 / 500.0)
    np.testing.assert_allclose(normal, (1 + kz) * np.exp(-kz), atol=1e-12)
    np.testing.assert_allclose(tangential, kz * np.exp(-kz), atol=1e-12)


@pytest.mark.parametrize("nu", NUS)
def test_equilibrium_fixes_the_long_wave_limits(nu):
    # G_n(0) = 1: all of a normal load reaches the base; G_t'(0) = 1: moment Q h
    small = 1e-6
    normal, tangential = layer.transfer(np.array([0.0, small]), nu)
    assert normal[0] == pytest.approx(1.0, abs=1e-12)
    assert tangential[0] == pytest.approx(0.0, abs=1e-12)
    assert tangential[1] / small == pytest.approx(1.0, rel=1e-5)


def test_incompressible_layer_is_a_regular_case():
    kh = np.linspace(0.0, 20.0, 201)
    at_half = np.array(layer.transfer(kh, 0.5))
    near_half = np.array(layer.transfer(kh, 0.5 - 1e-7))
    assert np.all(np.isfinite(at_half))
    np.testing.assert_allclose(at_half, near_half, atol=1e-6)


def test_the_rigid_base_raises_the_short_waves():
    # stress doubling at a rigid boundary: G / G_half-space -> 2 at short wavelengths
    kh = np.array([15.0, 25.0])
    normal, tangential = layer.transfer(kh, 0.5)
    assert normal / ((1 + kh) * np.exp(-kh)) == pytest.approx([2.0, 2.0], rel=0.1)
    assert tangential / (kh * np.exp(-kh)) == pytest.approx([2.0, 2.0], rel=0.1)


@pytest.mark.parametrize("kwargs, message", [
    (dict(kh=1.0, poisson_ratio=0.7), r"poisson_ratio must be a finite number in \[0, 0.5\], got 0.7"),
    (dict(kh=1.0, poisson_ratio=-0.1), r"poisson_ratio must .* got -0.1"),
    (dict(kh=1.0, poisson_ratio=math.nan), r"poisson_ratio must .* got nan"),
    (dict(kh=1.0, poisson_ratio="0.3"), r"poisson_ratio must .* got '0.3'"),
    (dict(kh=1.0, poisson_ratio=True), r"poisson_ratio must .* got True"),
    (dict(kh=-1.0, poisson_ratio=0.3), r"kh must be finite and >= 0"),
    (dict(kh=[1.0, math.inf], poisson_ratio=0.3), r"kh must be finite and >= 0"),
    (dict(kh=1.0, poisson_ratio=0.3, depth=0.0), r"depth must be a fraction of the thickness in \(0, 1\], got 0.0"),
    (dict(kh=1.0, poisson_ratio=0.3, depth=1.5), r"depth must be .* got 1.5"),
])
def test_transfer_rejects_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        layer.transfer(**kwargs)


# -- real space: equilibrium and the thick-layer limit -------------------------------------


@pytest.mark.parametrize("nu", NUS)
def test_point_load_base_stress_carries_the_load_and_the_moment(nu):
    # Equilibrium of the whole layer: base stresses integrate to P under a normal
    # load P, and to zero with first moment Q h under a tangential load Q.
    h = 2e-3
    r = np.linspace(0.0, layer.REACH * h, 30001)
    normal, tangential = layer.table(nu).point_stress(r / h)
    normal, tangential = normal / h**2, tangential / h**2
    assert np.trapezoid(2 * np.pi * r * normal, r) == pytest.approx(1.0, abs=1e-6)
    # tangential T33 = cos(phi) T(r): integral of x T33 over the plane is pi int r^2 T dr
    assert np.trapezoid(np.pi * r**2 * tangential, r) == pytest.approx(h, rel=1e-5)
    # compression ahead of the load (+x), relief behind it
    kx, _, _ = layer.layer_point_stress(np.array([h, -h]), np.zeros(2), h, nu)
    assert kx[0] > 0 > kx[1]


@pytest.mark.parametrize("nu", [0.3, 0.5])
@pytest.mark.parametrize("ratio", [0.3, 1.0, 2.0])
def test_cell_kernel_base_stress_integrates_to_the_force_and_moment(nu, ratio):
    # sensors on a fine lattice: the sum of T33 times the sensor area
    h, width = ratio * 1e-3, 1e-3
    step = width / 10   # the sum of a smooth decaying function converges fast
    reach = int(25 * max(h, width) / step)
    axis = np.arange(-reach, reach + 1) * step
    dx, dy = np.meshgrid(axis, axis)
    kx, ky, kz = kernels.layer_force_stress(dx, dy, h, width, nu)
    area = step * step
    assert kz.sum() * area == pytest.approx(1.0, abs=2e-4)
    assert kx.sum() * area == pytest.approx(0.0, abs=1e-6)
    assert (dx * kx).sum() * area == pytest.approx(h, rel=2e-4)
    assert (dy * ky).sum() * area == pytest.approx(h, rel=2e-4)
    assert (dy * kx).sum() * area == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("nu", NUS)
def test_thick_layer_matches_boussinesq_and_cerruti_at_the_same_depth(nu):
    # A load far smaller than the layer: T33 at depth d inside a layer of
    # thickness 40 d is the half-space closed form at depth d (within 0.5% of its peak).
    depth, thickness = 1e-3, 40e-3
    k, weight = gauss_panels(40.0 / depth, 0.05 / depth)
    normal, tangential = layer.transfer(k * thickness, nu, depth=depth / thickness)
    r = np.linspace(0.0, 5 * depth, 51)
    kr = np.outer(r, k)
    numeric_normal = j0(kr) @ (normal * k * weight) / (2 * np.pi)
    numeric_tangential = j1(kr) @ (tangential * k * weight) / (2 * np.pi)
    R = np.hypot(r, depth)
    boussinesq = 3 * depth**3 / (2 * np.pi * R**5)
    cerruti = 3 * r * depth**2 / (2 * np.pi * R**5)   # per cos(phi)
    assert np.abs(numeric_normal - boussinesq).max() <= 0.005 * boussinesq.max()
    assert np.abs(numeric_tangential - cerruti).max() <= 0.005 * cerruti.max()


def test_a_point_like_load_peaks_about_one_and_a_half_boussinesq():
    # the rigid hull under a nearly incompressible layer (DESIGN.md 2: 1.5x)
    for nu in (0.45, 0.5):
        normal, _ = layer.table(nu).point_stress(np.array([0.0]))
        assert 1.45 < normal[0] / (3 / (2 * np.pi)) < 1.6


def test_tables_are_cached_per_poisson_ratio_and_read_only():
    assert layer.table(0.45) is layer.table(0.45)
    tab = layer.table(0.45)
    with pytest.raises(ValueError):
        tab.potential[0] = 1.0


# -- the cell kernel through an independent path ---------------------------------------------


def fft_cell_kernel(h, width, nu, sub, size):
    # T33 of one newton spread over a width x width cell, by FFT of the transfer
    # functions times the cell's sinc on a fine periodic lattice.
    step = width / sub
    k = 2 * np.pi * np.fft.fftfreq(size, step)
    kxx, kyy = np.meshgrid(k, k)
    kk = np.hypot(kxx, kyy)
    table_kh = np.linspace(0.0, 40.0, 16001)   # 1-D table: linear interpolation error < 1e-6
    normal, tangential = (np.interp(kk * h, table_kh, g, right=0.0) for g in layer.transfer(table_kh, nu))
    box = np.sinc(kxx * width / (2 * np.pi)) * np.sinc(kyy * width / (2 * np.pi))
    with np.errstate(invalid="ignore"):
        along_x = np.where(kk > 0, -1j * tangential * kxx / kk, 0)
    tz = np.real(np.fft.ifft2(normal * box)) / step**2
    tx = np.real(np.fft.ifft2(along_x * box)) / step**2
    return step, tx, tz


@pytest.mark.parametrize("nu", [0.0, 0.45, 0.5])
@pytest.mark.parametrize("ratio", [0.1, 0.5, 1.0, 2.0])
def test_layer_cell_kernel_agrees_with_an_fft_of_the_transfer_functions(nu, ratio):
    width = 1.0
    sub, size = (32, 2048) if ratio < 0.3 else (16, 1024)
    step, tx, tz = fft_cell_kernel(ratio * width, width, nu, sub, size)
    index = np.arange(-5 * sub, 5 * sub + 1, sub // 4)     # every quarter pitch
    dx, dy = np.meshgrid(index * step, index * step)
    kx, ky, kz = kernels.layer_force_stress(dx, dy, ratio * width, width, nu)
    ref_z = tz[np.ix_(index % size, index % size)]
    ref_x = tx[np.ix_(index % size, index % size)]
    assert np.abs(kz - ref_z).max() <= 1e-4 * np.abs(ref_z).max()
    assert np.abs(kx - ref_x).max() <= 2e-4 * np.abs(ref_x).max()
    # the y component is the x one turned by 90 degrees
    np.testing.assert_allclose(ky, kx.T, atol=1e-9 * np.abs(kx).max())


@pytest.mark.parametrize("ratio", [0.5, 1.0, 3.0])
def test_edge_integrals_reproduce_the_half_space_closed_form(ratio, monkeypatch):
    # The layer kernel's divergence-theorem quadrature fed with half-space
    # functions must give Love's rectangle and the integrated Cerruti term.
    reference = layer.table(0.5)
    u = reference.radius
    with np.errstate(invalid="ignore", divide="ignore"):
        carried = np.where(u > 0, (1 - (1 + u * u) ** -1.5) / u**2, 1.5)
    half_space = layer.LayerTable(0.5, reference.reach, u, carried, -(1 + u * u) ** -1.5 / (2 * np.pi),
                                  reference.normal_point, reference.tangential_point)
    monkeypatch.setattr(layer, "table", lambda nu: half_space)
    offsets = np.arange(-4, 5) + 0.3
    dx, dy = np.meshgrid(offsets, offsets - 0.1)
    ours = kernels.layer_force_stress(dx, dy, ratio, 1.0, 0.5)
    closed = kernels.cell_force_stress(dx, dy, ratio, 1.0)
    for a, b in zip(ours, closed, strict=True):
        # what is left is the half-space tail beyond the table's reach (30 h)
        assert np.abs(a - b).max() <= 1e-5 * np.abs(b).max()


def test_layer_kernel_rejects_a_bad_poisson_ratio():
    with pytest.raises(ValueError, match=r"poisson_ratio must be a finite number in \[0, 0.5\], got 0.6"):
        kernels.layer_force_stress(np.zeros(1), np.zeros(1), 1e-3, 1e-3, 0.6)


# -- the matrix and the simulated data ---------------------------------------------------------


def test_stress_matrix_defaults_to_the_layer_with_the_grid_poisson_ratio():
    grid = SensorGrid.regular(5, 4, 1.5e-3, 1.5e-3, poisson_ratio=0.45)
    matrix = kernels.stress_matrix(grid)
    p = grid.positions
    kx, ky, kz = kernels.layer_force_stress(p[:, 0, None] - p[None, :, 0], p[:, 1, None] - p[None, :, 1],
                                            grid.thickness, grid.pitch, 0.45)
    np.testing.assert_allclose(matrix, np.hstack([kx, ky, kz]), rtol=1e-12, atol=1e-9 * kz.max())
    # Cz is symmetric positive definite: every kernel is even in the offset
    cz = matrix[:, 2 * grid.size:]
    np.testing.assert_allclose(cz, cz.T, rtol=1e-12, atol=1e-9 * cz.max())
    assert np.linalg.eigvalsh(cz).min() > 0


def test_irregular_layouts_use_the_same_kernel():
    grid = SensorGrid.regular(4, 3, 1.5e-3, 1.5e-3, poisson_ratio=0.3)
    irregular = SensorGrid(grid.positions, grid.thickness, grid.pitch, (grid.size,), poisson_ratio=0.3)
    np.testing.assert_allclose(kernels.stress_matrix(irregular), kernels.stress_matrix(grid),
                               rtol=1e-10, atol=1e-6)


@pytest.mark.parametrize("kernel", ["layer", "cell", "point"])
def test_sensor_size_averages_the_kernel_over_the_taxel(kernel):
    pitch, h, side = 1.5e-3, 0.75e-3, 1.2e-3
    grid = SensorGrid.regular(3, 3, pitch, h, sensor_size=side)
    point = SensorGrid.regular(3, 3, pitch, h)
    averaged = kernels.stress_matrix(grid, kernel)
    # brute force: the point-sensor kernel on a fine grid of the taxel
    fine = (np.arange(40) + 0.5) / 40 * side - side / 2
    u, v = np.meshgrid(fine, fine, indexing="ij")
    # every point of the taxel at once: sensors p shifted by it, (40 * 40, 9, 2), against the nodes q
    p, q = point.positions[None] + np.column_stack([u.ravel(), v.ravel()])[:, None], point.positions
    dx, dy = p[..., 0, None] - q[:, 0], p[..., 1, None] - q[:, 1]
    if kernel == "layer":
        parts = kernels.layer_force_stress(dx, dy, h, pitch, 0.5)
    elif kernel == "cell":
        parts = kernels.cell_force_stress(dx, dy, h, pitch)
    else:
        parts = kernels.half_space_point_stress(dx, dy, h)
    total = np.concatenate(parts, axis=2).mean(axis=0)
    assert np.abs(averaged - total).max() <= 2e-3 * np.abs(total).max()


@pytest.mark.parametrize("nu", [0.3, 0.5])
@pytest.mark.parametrize("ratio", [0.1, 0.5, 1.0, 2.0])
def test_simulated_layer_data_match_the_point_kernel_summed_over_the_load(nu, ratio):
    # Two independent paths from the transfer functions to the sensors: the
    # FFT convolution of loads.simulate, and the Hankel-tabulated point kernel
    # summed over a fine sampling of the same traction.
    pitch = 1.5e-3
    grid = SensorGrid.regular(10, 10, pitch, ratio * pitch, poisson_ratio=nu)
    contact = loads.hertz((0.4e-3, -0.3e-3), 2.5e-3, 1.0, shear_ratio=0.3, shear_direction=0.5)
    frame = loads.simulate(grid, contact, medium="layer")
    step = min(pitch / 41, ratio * pitch / 8)
    axis = np.arange(-3e-3, 3e-3, step) + step / 2
    x, y = (a.ravel() for a in np.meshgrid(axis + 0.4e-3, axis - 0.3e-3))
    fz = contact.profile(x, y)
    fz *= 1.0 / fz.sum()
    kx, ky, kz = layer.layer_point_stress(grid.positions[:, 0, None] - x, grid.positions[:, 1, None] - y,
                                          grid.thickness, nu)
    reference = (0.3 * math.cos(0.5) * kx + 0.3 * math.sin(0.5) * ky + kz) @ fz
    assert np.abs(frame.stress - reference).max() <= 5e-3 * reference.max()


def test_simulate_media_differ_as_the_physics_says():
    grid = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3, poisson_ratio=0.45)
    contact = loads.hertz((0.2e-3, 0.1e-3), 2.5e-3, 1.0)
    on_layer = loads.simulate(grid, contact, medium="layer")
    on_half_space = loads.simulate(grid, contact, medium="halfspace")
    assert on_layer.medium == "layer" and on_half_space.medium == "halfspace"
    np.testing.assert_array_equal(on_layer.forces, on_half_space.forces)
    # the hull concentrates the stress: higher, narrower peak, same total
    assert on_layer.stress.max() > 1.05 * on_half_space.stress.max()
    assert on_layer.stress.sum() == pytest.approx(on_half_space.stress.sum(), rel=0.03)


def test_simulate_rejects_an_unknown_medium():
    grid = SensorGrid.regular(4, 4, 1e-3, 1e-3)
    with pytest.raises(ValueError, match=r"medium must be one of \('layer', 'halfspace'\), got 'rubber'"):
        loads.simulate(grid, loads.hertz((0, 0), 1e-3, 1.0), medium="rubber")


# -- torsion: what a normal-stress skin cannot see (docs/torsion.md) -------------------------------


def full_field_matrix(kx, ky, nu):
    # d/dz [u_x, u_y, u_z, sigma_xz, sigma_yz, sigma_zz] for fields ~ e^{i k.x} (shear modulus 1):
    # all six components of the Navier equations, no split into P-SV and SH assumed.
    ik = 1j * np.array([kx, ky])
    # lambda / (lambda + 2 mu), 1 / (lambda + 2 mu), 2 mu lambda / (lambda + 2 mu): finite at nu = 0.5
    c1, c2, c3 = nu / (1 - nu), (1 - 2 * nu) / (2 * (1 - nu)), 2 * nu / (1 - nu)
    a = np.zeros((6, 6), complex)
    for j in range(6):
        ux, uy, uz, sxz, syz, szz = np.eye(6)[j]
        div_h = ik[0] * ux + ik[1] * uy
        lam_div = c1 * szz + c3 * div_h                 # lambda div u
        sxx, syy = lam_div + 2 * ik[0] * ux, lam_div + 2 * ik[1] * uy
        sxy = ik[0] * uy + ik[1] * ux
        a[:, j] = [sxz - ik[0] * uz, syz - ik[1] * uz, c2 * szz - c1 * div_h,
                   -(ik[0] * sxx + ik[1] * sxy), -(ik[0] * sxy + ik[1] * syy), -(ik[0] * sxz + ik[1] * syz)]
    return a


def full_field(kh, direction, nu, q, p, layers=10):
    # The bonded layer of unit thickness: traction (q, p) on the surface (sigma_iz = -(q, p)),
    # zero displacement at the base; the state at depths 0, 1/layers, ..., 1.
    a = full_field_matrix(kh * math.cos(direction), kh * math.sin(direction), nu)
    to_base = scipy.linalg.expm(a)
    surface_traction = -np.array([q[0], q[1], p], complex)
    surface_displacement = -np.linalg.solve(to_base[:3, :3], to_base[:3, 3:] @ surface_traction)
    states = [np.concatenate([surface_displacement, surface_traction])]
    one_layer = scipy.linalg.expm(a / layers)
    for _ in range(layers):
        states.append(one_layer @ states[-1])
    return np.array(states)


@pytest.mark.parametrize("nu", NUS)
def test_a_traction_across_k_drives_sh_motion_only_and_no_normal_stress(nu):
    # The full 3-D equations in wavenumber space, solved without assuming the decoupling that
    # solver.layer builds on: a traction across k moves the layer only across k (SH) and puts
    # no sigma_zz anywhere; a traction along k gives T33 = -i G_t |q| at the base, a pressure
    # G_n p, with layer.transfer's G_t and G_n (and its sign). Measured: |sigma_zz| <= 6e-12
    # of the traction (at kh = 8: expm carries e^8), u_z and u along k <= 7e-13, the G's to 1e-11.
    for kh in (0.1, 1.0, 3.0, 8.0):
        for direction in (0.0, 0.8, 2.5):
            along = np.array([math.cos(direction), math.sin(direction)])
            across = np.array([-along[1], along[0]])
            twist = full_field(kh, direction, nu, across, 0.0)
            assert np.abs(twist[:, 5]).max() <= 1e-10                # sigma_zz, every depth
            assert np.abs(twist[:, 2]).max() <= 1e-10                # u_z
            assert np.abs(twist[:, :2] @ along).max() <= 1e-10       # u along k
            assert np.abs(twist[0, :2] @ across) > 1e-3              # it does move: SH
            push = full_field(kh, direction, nu, along, 0.0)
            press = full_field(kh, direction, nu, (0.0, 0.0), 1.0)
            normal, tangential = layer.transfer(kh, nu)
            assert -push[-1, 5] == pytest.approx(-1j * tangential, abs=1e-10)   # T33 at the base
            assert -press[-1, 5] == pytest.approx(normal, abs=1e-10)
            assert np.abs(push[-1, :3]).max() <= 1e-10 and np.abs(press[-1, :3]).max() <= 1e-10
            assert abs(tangential) > 1e-3


def stream_function_traction(x, y):
    # psi = exp(-(u^2 + v^2)/2) (1 + 0.6 u + 0.3 u v), u = (x - x0)/sx, v = (y - y0)/sy: smooth,
    # lopsided, compact in effect; its gradient in closed form.
    x0, y0, sx, sy = 0.4e-3, -0.3e-3, 2.0e-3, 1.2e-3
    u, v = (x - x0) / sx, (y - y0) / sy
    bump, poly = np.exp(-(u * u + v * v) / 2), 1 + 0.6 * u + 0.3 * u * v
    d_dx = bump * (-u * poly + 0.6 + 0.3 * v) / sx
    d_dy = bump * (-v * poly + 0.3 * u) / sy
    return bump * poly, d_dx, d_dy


@pytest.mark.parametrize("nu", [0.3, 0.5])
def test_a_divergence_free_traction_puts_no_stress_on_the_sensors(nu):
    # Independent of loads.simulate: t = curl(psi e_z) = (dpsi/dy, -dpsi/dx) on a fine lattice
    # (h/6, 7 widths each way), summed through the closed-form Cerruti kernel and through the
    # layer's Hankel-table point kernel. The same field turned by 90 degrees at every point
    # (grad psi: same magnitude everywhere, curl-free) and the same magnitudes pointed one
    # way are the references. Measured: Cerruti 3e-13, layer 6e-9 of the one-way response.
    h, pitch = 1.5e-3, 1.5e-3
    grid = SensorGrid.regular(10, 10, pitch, h)
    step = h / 6
    axis = np.arange(-14e-3, 14e-3, step) + step / 2
    x, y = (a.ravel() for a in np.meshgrid(axis + 0.4e-3, axis - 0.3e-3))
    psi, d_dx, d_dy = stream_function_traction(x, y)
    area = step * step
    magnitude = np.hypot(d_dx, d_dy)
    fields = {"twist": (d_dy, -d_dx), "turned": (d_dx, d_dy),
              "one way": (magnitude * math.cos(0.7), magnitude * math.sin(0.7))}
    twist = fields["twist"]
    # a pure twist: no net force, a torque (2 int psi dA, by parts)
    assert abs(twist[0].sum()) + abs(twist[1].sum()) <= 1e-9 * magnitude.sum()
    torque = np.sum(x * twist[1] - y * twist[0]) * area
    assert torque == pytest.approx(2 * psi.sum() * area, rel=1e-9)
    assert abs(torque) > 0
    dx, dy = grid.positions[:, 0, None] - x, grid.positions[:, 1, None] - y
    r2 = dx * dx + dy * dy + h * h
    cerruti = (3 * h * h * dx / (2 * np.pi * r2**2.5), 3 * h * h * dy / (2 * np.pi * r2**2.5))
    on_layer = layer.layer_point_stress(dx, dy, h, nu)[:2]
    scale = magnitude.sum() * area / h**2            # the traction's total magnitude over h^2
    for (kx, ky), tolerance in ((cerruti, 1e-10), (on_layer, 1e-6)):
        stress = {name: (kx @ fx + ky @ fy) * area for name, (fx, fy) in fields.items()}
        seen = {name: np.abs(s).max() for name, s in stress.items()}
        assert seen["turned"] >= 0.01 * scale and seen["one way"] >= 0.01 * scale
        assert seen["twist"] <= tolerance * min(seen["turned"], seen["one way"])
