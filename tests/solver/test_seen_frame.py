"""The frame as a dense solve sees it: its contacts and the contact fit's view of them."""

import dataclasses

import numpy as np

from solver import SensorGrid, loads
from solver.inverse import DenseSolver
from solver.kernels import stress_matrix
from solver.threads import one_blas_thread


def test_frame_columns_are_the_sub_cells_of_the_region(reconstructor, sheared):
    # The frame is the sub-cell (bilinear hat) stress matrix restricted to the sensors near the contact
    # and to the sub-cells of its region's nodes: built here independently of _frame.
    r, b = reconstructor, np.asarray(sheared.stress)
    assert r.subdivision == 2
    seen = r._frame(b)
    frame, labels, nodes = seen.frame, seen.labels, seen.frame.column_node
    m, cells = r.grid.size, 4
    region = np.flatnonzero(labels)
    assert frame.contacts == labels.max() == 1
    distance = np.linalg.norm(r.grid.positions[:, None] - r.grid.positions[None, region], axis=2).min(axis=1)
    rows = np.flatnonzero(distance <= r._rings * r.grid.pitch * 1.0001)
    columns = (np.arange(cells)[:, None] * m + region).ravel()  # sub-cell q of node j: q m + j
    full = stress_matrix(r.grid, r.kernel, subdivision=2, profile=r.profile)
    width = cells * m
    np.testing.assert_array_equal(frame.stress, b[rows])
    for k, part in enumerate((frame.fit_x, frame.fit_y, frame.fit_z)):
        np.testing.assert_array_equal(part, full[np.ix_(rows, columns + k * width)])
    np.testing.assert_array_equal(nodes, np.tile(region, cells))
    np.testing.assert_array_equal(frame.column_contact, np.zeros(columns.size, int))
    assert frame.row_contact.shape == (rows.size, 1) and frame.row_contact.all()
    # the answer is one force per node: the sum of its sub-cells' profile
    # on one BLAS thread, as the solve runs: the same products, summed in the same order
    with one_blas_thread():
        choice = r.efficiency.choose(frame)
    result = r.solve(b)
    np.testing.assert_allclose(result.forces[:, 2], np.bincount(nodes, weights=choice.profile, minlength=m),
                               rtol=1e-12, atol=0)
    np.testing.assert_array_equal(result.contacts[0].nodes, labels == 1)


def test_a_frame_whose_contacts_cover_the_same_nodes_shares_the_view_of_the_frame_before():
    # Playback and live mode: the frame after covers the same nodes (the same load, fresh 1% noise),
    # so its view shares the frame before's matrices and the answer is a fresh solver's exactly;
    # a load moved by two pitches gets a view of its own.
    grid = SensorGrid.regular(14, 12, 2e-3, 2e-3)
    contact = loads.hertz((0.5e-3, -0.3e-3), 5e-3, 1.0, shear_ratio=0.3, shear_direction=1.0)
    rng = np.random.default_rng(3)  # fixed: these draws keep the contact's nodes
    first, after = (loads.simulate(grid, contact, noise=0.01, rng=rng).stress for _ in range(2))
    moved = loads.simulate(grid, dataclasses.replace(contact, center=(4.5e-3, -0.3e-3)), noise=0.01,
                           rng=rng).stress
    playing = DenseSolver(grid)
    with one_blas_thread():
        playing.solve(first)
        before = playing._recent[0]
        result = playing.solve(after)
        seen = playing._recent[0]
        assert np.array_equal(seen.labels, before.labels)
        for part in ("fit_x", "fit_y", "fit_z", "row_contact", "column_id"):
            assert getattr(seen.frame, part) is getattr(before.frame, part)
        assert seen.nodes is before.nodes
        assert seen.key == np.asarray(after).tobytes() and not np.array_equal(seen.frame.stress,
                                                                                before.frame.stress)
        fresh = DenseSolver(grid)
        fresh.solve(first)  # the same solve before it: the fit starts from the same set
        np.testing.assert_array_equal(result.forces, fresh.solve(after).forces)
        playing.solve(moved)
        assert not np.array_equal(playing._recent[0].labels, seen.labels)
        assert playing._recent[0].frame.fit_z is not seen.frame.fit_z
        # a frame seen with another fallback (a budget's whole cells, contacts left out) is not shared
        other = dataclasses.replace(before, fallback="whole-cell fit: ...")
        assert playing._frame(np.asarray(after), like=other).frame.fit_z is not before.frame.fit_z
        assert playing._frame(np.asarray(after), like=before).frame.fit_z is before.frame.fit_z
