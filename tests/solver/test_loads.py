"""Simulated contacts: totals, shear, torsion, noise and input checks."""

import math

import numpy as np
import pytest

from solver import SensorGrid, loads


@pytest.fixture(scope="module")
def grid():
    return SensorGrid.regular(16, 16, pitch=2e-3, thickness=2e-3)


@pytest.mark.parametrize("make", [
    lambda **kw: loads.hertz((0.3e-3, -0.5e-3), 5e-3, 1.3, **kw),
    lambda **kw: loads.cone((0.3e-3, -0.5e-3), 5e-3, 1.3, **kw),
    lambda **kw: loads.flat_punch((0.3e-3, -0.5e-3), 4e-3, 1.3, **kw),
    lambda **kw: loads.ellipse((0.3e-3, -0.5e-3), (6e-3, 3e-3), 1.3, angle=0.4, **kw),
    lambda **kw: loads.ring((0.3e-3, -0.5e-3), 2e-3, 5e-3, 1.3, **kw),
], ids=["hertz", "cone", "flat_punch", "ellipse", "ring"])
def test_totals_and_shear_are_as_requested(grid, make):
    frame = loads.simulate(grid, make(shear_ratio=0.4, shear_direction=2.0))
    total = frame.forces.sum(0)
    assert total[2] == pytest.approx(1.3, rel=1e-9)
    np.testing.assert_allclose(total[:2], 0.4 * 1.3 * np.array([math.cos(2.0), math.sin(2.0)]), rtol=1e-9)
    # compression ahead of the shear, relief behind: the stress centroid moves along theta
    still = loads.simulate(grid, make())
    shift = (frame.stress - still.stress) @ grid.positions
    assert math.atan2(shift[1], shift[0]) == pytest.approx(2.0, abs=0.05)
    np.testing.assert_allclose(frame.stress, frame.clean_stress)


def test_torsion_carries_the_torque_and_no_net_shear(grid):
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), 5e-3, 1.0, torsion=2e-3))
    f, p = frame.forces, grid.positions
    # nodal forces act at node positions, so the torque is only approximately kept
    torque = np.sum(p[:, 0] * f[:, 1] - p[:, 1] * f[:, 0])
    assert torque == pytest.approx(2e-3, rel=0.1)
    np.testing.assert_allclose(f[:, :2].sum(0), 0, atol=1e-12)


@pytest.mark.parametrize("squeeze", [0.3, -0.2])
def test_a_squeeze_pushes_the_halves_towards_each_other_with_no_net_force(grid, squeeze):
    direction = 0.6
    u = np.array([math.cos(direction), math.sin(direction)])
    centre = np.array([0.3e-3, -0.5e-3])
    frame = loads.simulate(grid, loads.hertz(tuple(centre), 5e-3, 1.0, shear_ratio=0.1, shear_direction=2.0,
                                             squeeze=squeeze, squeeze_direction=direction))
    still = loads.simulate(grid, loads.hertz(tuple(centre), 5e-3, 1.0, shear_ratio=0.1, shear_direction=2.0))
    f = frame.forces - still.forces  # the squeeze's own traction, node by node
    np.testing.assert_allclose(frame.forces[:, 2], still.forces[:, 2])
    np.testing.assert_allclose(f[:, :2].sum(0), 0, atol=1e-3 * abs(squeeze))  # the halves cancel
    # every node's squeeze force lies along u, pointing at the line through the centre (a node on
    # the line holds sub-cells of both sides), squeeze times its normal force at most
    along = f[:, :2] @ u
    np.testing.assert_allclose(f[:, :2], along[:, None] * u, atol=1e-12)
    side = (grid.positions - centre) @ u
    away = side * np.sign(squeeze)
    assert np.all(along[away > grid.pitch] <= 1e-12) and np.all(along[away < -grid.pitch] >= -1e-12)
    np.testing.assert_array_less(np.abs(along), abs(squeeze) * frame.forces[:, 2] + 1e-12)
    # away from the line, each node's is the whole squeeze of its normal force
    far = np.abs(side) > grid.pitch
    np.testing.assert_allclose(np.abs(along[far]), abs(squeeze) * frame.forces[far, 2], rtol=1e-9, atol=1e-12)


# -- torsion is invisible (docs/torsion.md) ---------------------------------------------------------


def shear_of_equal_magnitude(torque, radius, force):
    # A Hertzian twist's traction is k p r (k = T / int p r^2 dA), so its magnitudes add up to
    # int |t| dA = T (pi/16) / (2/15) / a; the shear ratio that spreads the same total
    # magnitude along one direction is that over the normal force.
    return 15 * math.pi * torque / (32 * radius * force)


@pytest.mark.parametrize("medium", ["layer", "halfspace"])
@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_a_twist_leaves_every_sensor_reading_unchanged(medium, ratio):
    # A round contact's torsion is a circumferential traction k p(r) r: divergence-free, so
    # no normal-stress skin can see it (docs/torsion.md). Measured, default integration, h/pitch
    # 0.5 to 2: the twist changes the readings by 0.8e-4 to 4.9e-4 of what the same traction
    # magnitudes pointed one way change them (6e-5 of the peak at most); the rest is the
    # sub-cell discretisation of the traction (next test), so 1e-3 is the bar.
    pitch, (a, force, torque) = 1.5e-3, (3e-3, 1.0, 1e-3)
    grid = SensorGrid.regular(16, 16, pitch, ratio * pitch, poisson_ratio=0.45)
    centre = (0.37e-3, -0.21e-3)   # off the sensor lattice
    mu = shear_of_equal_magnitude(torque, a, force)
    still, twist, shear = (
        loads.simulate(grid, loads.hertz(centre, a, force, **kw), medium=medium)
        for kw in ({}, dict(torsion=torque), dict(shear_ratio=mu, shear_direction=0.7)))
    # the twist is there: its nodal forces carry the torque about the centre
    f, p = twist.forces, grid.positions - centre
    assert np.sum(p[:, 0] * f[:, 1] - p[:, 1] * f[:, 0]) == pytest.approx(torque, rel=0.1)
    seen = np.abs(shear.stress - still.stress).max()
    assert seen >= 0.05 * still.stress.max()    # one-way shear shows: 10% to 15% of the peak
    assert np.abs(twist.stress - still.stress).max() <= 1e-3 * seen


def test_what_is_left_of_a_twist_is_the_discretisation_of_its_traction():
    # Refining the sub-cells and their profile samples takes the residue towards zero
    # (measured at h = pitch: 1.8e-4 and 1.5e-4 of the one-way shear's change at the default
    # 9 sub-cells per pitch x 4 samples, 2.5e-6 and 2.1e-6 at 33 x 8, layer and half-space).
    grid = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3, poisson_ratio=0.45)
    centre, a, force, torque = (0.37e-3, -0.21e-3), 3e-3, 1.0, 1e-3
    shear = loads.hertz(centre, a, force, shear_ratio=shear_of_equal_magnitude(torque, a, force))
    for medium in ("layer", "halfspace"):
        seen = np.abs(loads.simulate(grid, shear, medium=medium).stress
                      - loads.simulate(grid, loads.hertz(centre, a, force), medium=medium).stress).max()
        residue = []
        for fine in (dict(), dict(subdivisions=33, supersample=8)):
            still, twist = (loads.simulate(grid, loads.hertz(centre, a, force, torsion=t), medium=medium,
                                           **fine).stress for t in (0.0, torque))
            residue.append(np.abs(twist - still).max() / seen)
        assert residue[1] <= 1e-5 and residue[1] <= residue[0] / 20


def test_a_non_round_contact_s_circumferential_traction_is_not_a_pure_twist():
    # k p r about the centre of an ellipse crosses its iso-pressure lines: that traction has a
    # divergence, and its divergence shows (measured 11% of the peak through the layer, 8%
    # through the half-space); only its curl part is invisible.
    grid = SensorGrid.regular(16, 16, 1.5e-3, 1.5e-3, poisson_ratio=0.45)
    for medium in ("layer", "halfspace"):
        still, twisted = (loads.simulate(grid, loads.ellipse((0.37e-3, -0.21e-3), (4e-3, 2e-3), 1.0, angle=0.3,
                                                             torsion=t), medium=medium).stress
                          for t in (0.0, 1e-3))
        assert np.abs(twisted - still).max() >= 0.05 * still.max()


def test_several_contacts_add_up(grid):
    a = loads.hertz((-8e-3, -8e-3), 4e-3, 0.5, shear_ratio=0.2)
    b = loads.flat_punch((8e-3, 6e-3), 3e-3, 0.7, shear_ratio=0.3, shear_direction=1.0)
    both = loads.simulate(grid, [a, b], subdivisions=16)
    apart = [loads.simulate(grid, c, subdivisions=16) for c in (a, b)]
    # the FFT lattice differs between the runs: equal up to its wrap-around (< 1e-6 of the peak)
    np.testing.assert_allclose(both.stress, apart[0].stress + apart[1].stress, rtol=0,
                               atol=1e-6 * np.abs(both.stress).max())
    np.testing.assert_allclose(both.forces, apart[0].forces + apart[1].forces, atol=1e-15)


def test_noise_is_relative_to_the_peak_and_seeded(grid):
    contact = loads.hertz((0.0, 0.0), 5e-3, 1.0)
    one = loads.simulate(grid, contact, noise=0.01, rng=4)
    two = loads.simulate(grid, contact, noise=0.01, rng=4)
    np.testing.assert_array_equal(one.stress, two.stress)
    deviation = np.std(one.stress - one.clean_stress)
    assert deviation == pytest.approx(0.01 * one.clean_stress.max(), rel=0.15)


def test_load_off_the_skin_is_counted_nowhere():
    grid = SensorGrid.regular(8, 8, 2e-3, 1e-3)
    # centred on the right edge of the skin: about half of it is off
    frame = loads.simulate(grid, loads.hertz((8e-3, 0.0), 3e-3, 1.0))
    assert 0.4 < frame.forces[:, 2].sum() < 0.6


def test_fine_integration_converges(grid):
    contact = loads.hertz((0.2e-3, 0.1e-3), 5e-3, 1.0)
    coarse = loads.simulate(grid, contact, subdivisions=8).stress
    fine = loads.simulate(grid, contact, subdivisions=32).stress
    assert np.abs(coarse - fine).max() < 5e-3 * fine.max()


def test_arrays_are_read_only(grid):
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0))
    for array in (frame.stress, frame.clean_stress, frame.forces):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0


@pytest.mark.parametrize("make, message", [
    (lambda: loads.hertz((0.0, 0.0), -1e-3, 1.0), "semi_axes must be two positive radii"),
    (lambda: loads.hertz((0.0, math.nan), 1e-3, 1.0), "center must be two finite coordinates"),
    (lambda: loads.hertz((0.0, 0.0), 1e-3, math.inf), "force must be finite"),
    (lambda: loads.hertz((0.0, 0.0), 1e-3, 1.0, shear_ratio=-0.1), "shear_ratio must be finite and >= 0"),
    (lambda: loads.ring((0.0, 0.0), 3e-3, 2e-3, 1.0), r"inner_radius must be in \[0, outer radius"),
    (lambda: loads.flat_punch((0.0, 0.0), 1e-3, 1.0, clip=1.5), r"clip must be in \(0, 1\)"),
    (lambda: loads.ContactLoad("blob", (0, 0), (1e-3, 1e-3), 1.0), "shape must be one of"),
    (lambda: loads.hertz((0.0, 0.0), 1e-3, 1.0, squeeze=math.nan), "squeeze must be finite, got nan"),
    (lambda: loads.hertz((0.0, 0.0), 1e-3, 1.0, squeeze_direction=math.inf),
     "squeeze_direction must be finite, got inf"),
], ids=["radius", "center", "force", "shear", "ring", "clip", "shape", "squeeze", "squeeze_direction"])
def test_invalid_contacts_are_rejected(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_invalid_simulation_arguments_are_rejected(grid):
    contact = loads.hertz((0.0, 0.0), 3e-3, 1.0)
    with pytest.raises(ValueError, match="contacts must be one or more ContactLoad"):
        loads.simulate(grid, [])
    with pytest.raises(ValueError, match="noise must be finite and >= 0, got -0.1"):
        loads.simulate(grid, contact, noise=-0.1)
