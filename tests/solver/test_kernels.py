"""Forward model against closed forms and fine quadrature."""

import math

import numpy as np
import pytest

from solver import SensorGrid, loads
from solver.kernels import (
    cell_force_stress,
    half_space_point_stress,
    layer_force_stress,
    stress_matrix,
    subcell_offsets,
    taxel_points,
)


def love_rectangle(q, L, B, z):
    # Love's uniform rectangle below one corner, written out independently of solver.kernels
    r1, r2, r3 = math.hypot(L, z), math.hypot(B, z), math.sqrt(L * L + B * B + z * z)
    return q / (2 * math.pi) * (math.atan(L * B / (z * r3)) + L * B * z / r3 * (1 / r1**2 + 1 / r2**2))


def test_hertz_on_axis_matches_closed_form():
    # T33(0, z) = p0 a^2 / (a^2 + z^2) on a half-space, from the fine integration of the continuous load
    a, force, z = 4e-3, 2.0, 3e-3
    p0 = 3 * force / (2 * math.pi * a * a)
    grid = SensorGrid.regular(1, 1, pitch=30e-3, thickness=z)
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), a, force), subdivisions=600, medium="halfspace")
    assert frame.stress[0] == pytest.approx(p0 * a * a / (a * a + z * z), rel=2e-3)


@pytest.mark.parametrize("point", [(0.0, 0.0), (0.7e-3, -0.2e-3), (3e-3, 2e-3), (-5e-3, 0.4e-3)])
def test_cell_normal_kernel_is_loves_rectangle(point):
    # a cell of side w centred at the origin = signed sum of four corner rectangles
    w, z = 2e-3, 1.2e-3
    q = 1.0 / (w * w)
    x, y = point
    total = 0.0
    for u, su in ((w / 2 - x, 1), (-w / 2 - x, -1)):
        for v, sv in ((w / 2 - y, 1), (-w / 2 - y, -1)):
            sign = su * sv * math.copysign(1, u) * math.copysign(1, v)
            total += sign * love_rectangle(q, abs(u), abs(v), z)
    kz = cell_force_stress(np.array(x), np.array(y), z, w)[2]
    assert float(kz) == pytest.approx(total, rel=1e-10)


@pytest.mark.parametrize("point", [(0.0, 0.0), (1.1e-3, 0.3e-3), (-2.5e-3, 1.9e-3), (0.3e-3, -4e-3)])
def test_cell_kernel_matches_fine_quadrature_of_point_kernel(point):
    w, z, n = 2e-3, 0.8e-3, 600
    s = ((np.arange(n) + 0.5) / n - 0.5) * w
    u, v = np.meshgrid(s, s)
    expected = [k.mean() for k in half_space_point_stress(point[0] - u, point[1] - v, z)]
    got = cell_force_stress(np.array(point[0]), np.array(point[1]), z, w)
    scale = max(abs(e) for e in expected)
    np.testing.assert_allclose(got, expected, atol=1e-5 * scale)


def test_uniform_pressure_over_a_large_area_reads_back_as_that_pressure():
    # every cell of a wide skin carries q * pitch^2; the central sensor reads q
    q, pitch, h = 5e3, 2e-3, 1e-3
    grid = SensorGrid.regular(41, 41, pitch, h)
    C = stress_matrix(grid, "cell")
    m = grid.size
    stress = C[:, 2 * m:] @ np.full(m, q * pitch * pitch)
    centre = (41 * 41) // 2
    assert stress[centre] == pytest.approx(q, rel=2e-3)


@pytest.mark.parametrize("kernel", ["cell", "point"])
def test_cerruti_term_is_antisymmetric(kernel):
    grid = SensorGrid.regular(7, 5, 2e-3, 1.5e-3)
    C = stress_matrix(grid, kernel)
    m = grid.size
    cx, cy, cz = C[:, :m], C[:, m:2 * m], C[:, 2 * m:]
    # swapping sensor and node flips the sign of the tangential kernels
    np.testing.assert_allclose(cx, -cx.T, atol=1e-12 * np.abs(cx).max())
    np.testing.assert_allclose(cy, -cy.T, atol=1e-12 * np.abs(cy).max())
    np.testing.assert_allclose(cz, cz.T, rtol=1e-12)
    assert np.all(np.diag(cx) == 0)
    # ahead of a +x load the sensor is compressed
    k = 2 * 7 + 3
    assert cx[k + 1, k] > 0 > cx[k - 1, k]


def test_regular_and_general_assembly_agree():
    grid = SensorGrid.regular(6, 4, 1.5e-3, 2e-3)
    shifted = SensorGrid(grid.positions * [1, 1 + 1e-7], grid.thickness, grid.pitch, (24,))
    assert not shifted.is_regular
    for kernel in ("cell", "point"):
        regular, general = stress_matrix(grid, kernel), stress_matrix(shifted, kernel)
        np.testing.assert_allclose(regular, general, rtol=1e-5, atol=1e-9)
        # stored by column on both paths: the solver reads a node's column without a copy
        assert regular.flags.f_contiguous and general.flags.f_contiguous


def test_a_sub_cell_column_is_the_cell_kernel_at_that_sub_cells_centre():
    pitch = 2e-3
    offsets = subcell_offsets(pitch, 2)
    # row-major within the cell, x fastest
    np.testing.assert_allclose(offsets / pitch, [[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
    grid = SensorGrid.regular(4, 4, pitch, pitch)
    matrix = stress_matrix(grid, "cell", subdivision=2)
    m, x, y = grid.size, grid.positions[:, 0], grid.positions[:, 1]
    for q, j in ((1, 5), (2, 10)):
        source = grid.positions[j] + offsets[q]
        expected = cell_force_stress(x - source[0], y - source[1], grid.thickness, pitch / 2)[2]
        np.testing.assert_allclose(matrix[:, (2 * 4 + q) * m + j], expected, rtol=1e-12)


@pytest.mark.parametrize("subdivision", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("sensor_size", [0.0, 0.6], ids=["point-sensors", "taxels"])
def test_every_sub_cell_column_is_its_kernel_read_directly(subdivision, sensor_size):
    # Three quarters of the sub-cells read mirrored tables: each column (all three components)
    # against the half-space cell kernel at its own sub-cell, averaged over the taxel here. The
    # pitch 1.55 mm puts an odd subdivision's middle centre a rounding error off zero (it once
    # left that sub-cell's table unbuilt).
    pitch = 1.55e-3
    grid = SensorGrid.regular(5, 4, pitch, pitch, sensor_size=sensor_size * pitch)
    matrix = stress_matrix(grid, "cell", subdivision=subdivision)
    m, cells, width = grid.size, subdivision**2, pitch / subdivision
    points, weights = taxel_points(grid)
    x, y = grid.positions[:, 0], grid.positions[:, 1]
    for q, offset in enumerate(subcell_offsets(pitch, subdivision)):
        for j in (0, 7, m - 1):
            source = grid.positions[j] + offset
            expected = sum(w * np.array(cell_force_stress(x + u - source[0], y + v - source[1],
                                                          grid.thickness, width))
                           for (u, v), w in zip(points, weights, strict=True))
            for component in range(3):
                column = matrix[:, (component * cells + q) * m + j]
                np.testing.assert_allclose(column, expected[component], rtol=0,
                                           atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("kernel", ["cell", "layer"])
@pytest.mark.parametrize("thickness_ratio", [0.25, 0.5, 1.0])
def test_a_bilinear_column_is_the_finely_integrated_hat_load(kernel, thickness_ratio):
    # The hats of sub-cells 0 (evaluated) and 3 (read from 0's mirror image) of an inner node,
    # half-width pitch / 2, built here as 48 x 48 uniform squares weighted by the hat's height:
    # not the shifted-sub-cell quadrature the matrix uses. Measured agreement 0.09% of the
    # column's peak or better; a uniform sub-cell's columns are 7% to 57% off in their worst
    # component (the test tells the two apart).
    pitch = 2e-3
    grid = SensorGrid.regular(6, 6, pitch, thickness_ratio * pitch)
    m, node, half = grid.size, 14, pitch / 2
    matrix = stress_matrix(grid, kernel, subdivision=2, profile="bilinear")
    uniform = stress_matrix(grid, kernel, subdivision=2)
    fine = 48
    u = (np.arange(fine) + 0.5) / fine * 2 * half - half
    ux, uy = (a.ravel() for a in np.meshgrid(u, u))
    height = (1 - np.abs(ux) / half) * (1 - np.abs(uy) / half)
    height /= height.sum()
    for q in (0, 3):
        centre = grid.positions[node] + subcell_offsets(pitch, 2)[q]
        dx = grid.positions[:, :1] - (centre[0] + ux)
        dy = grid.positions[:, 1:] - (centre[1] + uy)
        width = 2 * half / fine
        parts = (cell_force_stress(dx, dy, grid.thickness, width) if kernel == "cell"
                 else layer_force_stress(dx, dy, grid.thickness, width, grid.poisson_ratio))
        uniform_off = 0.0
        for component, part in enumerate(parts):
            expected = part @ height
            column = (component * 4 + q) * m + node
            scale = np.abs(expected).max()
            assert np.abs(matrix[:, column] - expected).max() <= 1e-3 * scale
            uniform_off = max(uniform_off, np.abs(uniform[:, column] - expected).max() / scale)
        assert uniform_off >= 0.05


def test_a_smaller_grid_reads_the_offset_tables_of_a_larger_one(monkeypatch):
    # The region solver's windows are sub-grids of one skin: a window after a larger one of the
    # same geometry takes the centre of its kernel tables instead of evaluating them again.
    from collections import OrderedDict

    import solver.kernels as kernels

    monkeypatch.setattr(kernels, "_TABLES", OrderedDict())
    small, large = SensorGrid.regular(6, 5, 2e-3, 2e-3), SensorGrid.regular(9, 9, 2e-3, 2e-3)
    alone = stress_matrix(small, "layer", subdivision=2, profile="bilinear")
    stress_matrix(large, "layer", subdivision=2, profile="bilinear")
    computed = []
    original = kernels._compute_tables
    monkeypatch.setattr(kernels, "_compute_tables", lambda *args: computed.append(args) or original(*args))
    again = stress_matrix(small, "layer", subdivision=2, profile="bilinear")
    assert computed == []
    # the same kernel values, evaluated in other blocks: equal up to rounding
    np.testing.assert_allclose(again, alone, rtol=0, atol=1e-14 * np.abs(alone).max())
    # another geometry (here the uniform profile) has tables of its own
    stress_matrix(small, "layer", subdivision=2)
    assert len(computed) == 1


@pytest.mark.parametrize("change", [dict(thickness=1.5e-3), dict(pitch=2.5e-3), dict(poisson_ratio=0.45),
                                    dict(sensor_size=1e-3)])
def test_grids_that_differ_in_anything_the_kernel_reads_do_not_share_tables(change, monkeypatch):
    from collections import OrderedDict

    import solver.kernels as kernels

    options = dict(pitch=2e-3, thickness=2e-3, poisson_ratio=0.5, sensor_size=0.0)
    other = {**options, **change}

    def grid(o):
        return SensorGrid.regular(5, 5, o["pitch"], o["thickness"], poisson_ratio=o["poisson_ratio"],
                                  sensor_size=o["sensor_size"])
    monkeypatch.setattr(kernels, "_TABLES", OrderedDict())
    fresh = stress_matrix(grid(other), "layer", subdivision=2, profile="bilinear")
    monkeypatch.setattr(kernels, "_TABLES", OrderedDict())
    stress_matrix(SensorGrid.regular(8, 8, options["pitch"], options["thickness"]), "layer", subdivision=2,
                  profile="bilinear")
    after = stress_matrix(grid(other), "layer", subdivision=2, profile="bilinear")
    np.testing.assert_allclose(after, fresh, rtol=0, atol=1e-14 * np.abs(fresh).max())


def test_the_offset_tables_kept_stay_within_their_count_and_bytes(monkeypatch):
    from collections import OrderedDict

    import solver.kernels as kernels

    monkeypatch.setattr(kernels, "_TABLES", OrderedDict())
    grids = [SensorGrid.regular(6, 6, 2e-3, t) for t in (1.5e-3, 2e-3, 2.5e-3)]
    for grid in grids:
        stress_matrix(grid, "cell", subdivision=2)
    assert len(kernels._TABLES) == 3
    # a table of a 6x6 grid at subdivision 2: 4 sub-cells x 3 components x 11 x 11 offsets
    one = 4 * 3 * 11 * 11 * 8
    monkeypatch.setattr(kernels, "_TABLES_BYTES", 2 * one)
    stress_matrix(grids[0], "cell", subdivision=2)  # kept: the most recent now, no eviction yet
    stress_matrix(SensorGrid.regular(6, 6, 2e-3, 3e-3), "cell", subdivision=2)
    # the least recently used two went: what is kept fits the budget, the latest first
    assert [key[2] for key in kernels._TABLES] == [1.5e-3, 3e-3]
    monkeypatch.setattr(kernels, "_TABLES_KEPT", 1)
    stress_matrix(grids[1], "cell", subdivision=2)
    assert [key[2] for key in kernels._TABLES] == [2e-3]
    # the latest is kept even when it alone is over the budget
    monkeypatch.setattr(kernels, "_TABLES_BYTES", 1)
    stress_matrix(grids[2], "cell", subdivision=2)
    assert [key[2] for key in kernels._TABLES] == [2.5e-3]


def test_two_threads_needing_the_same_tables_compute_them_once(monkeypatch):
    # a viewer's worker and the trade-off tool may build solvers of one geometry at once: the
    # second waits for the first's tables instead of computing them too (twice the time and memory)
    import threading
    import time
    from collections import OrderedDict

    import solver.kernels as kernels

    monkeypatch.setattr(kernels, "_TABLES", OrderedDict())
    computed = []
    original = kernels._compute_tables
    asking = threading.Event()

    def slow(*args):
        computed.append(args)
        asking.wait(5)  # until the other thread has asked for the same tables
        time.sleep(0.1)  # and reached the wait for them
        return original(*args)
    monkeypatch.setattr(kernels, "_compute_tables", slow)
    grid = SensorGrid.regular(6, 6, 2e-3, 2e-3)
    matrices, errors = [None, None], []

    def build(i):
        try:
            if i == 1:
                deadline = time.monotonic() + 5
                while not computed and time.monotonic() < deadline:  # the first thread is computing
                    time.sleep(0.001)
                asking.set()
            matrices[i] = stress_matrix(grid, "cell", subdivision=2)
        except Exception as error:  # an exception in a thread would not fail the test
            errors.append(error)
    threads = [threading.Thread(target=build, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert len(computed) == 1
    np.testing.assert_array_equal(matrices[0], matrices[1])


def test_unknown_profile_is_rejected():
    with pytest.raises(ValueError, match="profile must be one of .* got 'spline'"):
        stress_matrix(SensorGrid.regular(2, 2, 1e-3, 1e-3), "cell", subdivision=2, profile="spline")


def test_cell_kernel_keeps_the_total_force_where_the_point_kernel_loses_it():
    grid = SensorGrid.regular(25, 25, 2e-3, 1e-3)  # h / pitch = 0.5
    m = grid.size
    centre = m // 2
    # pascals per newton integrated over the sensors' cells: 1 when the total is kept
    cell = stress_matrix(grid, "cell")[:, 2 * m + centre].sum() * grid.pitch**2
    point = stress_matrix(grid, "point")[:, 2 * m + centre].sum() * grid.pitch**2
    assert cell == pytest.approx(1.0, abs=1e-3)
    assert abs(point - 1.0) > 0.5


def test_unknown_kernel_is_rejected():
    with pytest.raises(ValueError, match="kernel must be one of .* got 'spline'"):
        stress_matrix(SensorGrid.regular(2, 2, 1e-3, 1e-3), "spline")
