"""Make the bundled sample recordings in ``sample_data/`` from :mod:`solver.loads`.

``python -m tools.make_samples [OUTDIR]`` rewrites them; every sample
carries its true nodal forces and the whole geometry (the elastomer's Poisson
ratio and the taxel size too). Seeds are fixed, so the files are reproducible.
The pinch, three-contact, twist and broad-press samples are ``tactile-sim``'s
scenes (:data:`tactile_viewer.sources.simulated.SCENES`), integrated on ``loads``'
default (finer) sub-cell lattice.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from solver import SensorGrid, loads
from tactile_viewer.io.files import save
from tactile_viewer.io.recording import Recording
from tactile_viewer.sources.simulated import scene_contacts

PITCH = 2e-3
THICKNESS = 2e-3
POISSON_RATIO = 0.5  # silicone elastomers are nearly incompressible
SENSOR_SIZE = 0.0  # point sensors
RATE = 30.0  # frames per second
NOISE = 0.01


def _record(grid, contacts_at, count, description, seed, rate=RATE):
    # the recording keeps `grid` itself, so the file says which nu and taxel size made the frames;
    # one generator for the whole recording: frames get independent noise
    rng = np.random.default_rng(seed)
    frames, truth = [], []
    for k in range(count):
        frame = loads.simulate(grid, contacts_at(k / rate), noise=NOISE, rng=rng, medium="layer")
        frames.append(frame.stress)
        truth.append(frame.forces)
    return Recording(grid, np.array(frames), np.arange(count) / rate, np.array(truth), description)


def _scene(grid, name, period):
    """``contacts_at(t)``: ``tactile-sim``'s scene ``name`` going once round in ``period`` seconds."""
    return lambda t: scene_contacts(name, grid, (t / period) % 1.0)


def _ramp(t, rise=0.5):
    return min(1.0, 0.1 + 0.9 * t / rise)


def make_all(outdir: Path) -> list[Path]:
    """Simulate every sample and write it to ``outdir``; returns the paths written."""
    grid = SensorGrid.regular(16, 16, PITCH, THICKNESS, poisson_ratio=POISSON_RATIO, sensor_size=SENSOR_SIZE)
    large = SensorGrid.regular(32, 32, PITCH, THICKNESS, poisson_ratio=POISSON_RATIO, sensor_size=SENSOR_SIZE)
    skin = "16x16, pitch 2 mm, thickness 2 mm (bonded layer, nu 0.5), 1% noise."
    samples = {
        "hertz_static.npz": _record(
            grid, lambda t: loads.hertz((0.6e-3, -0.4e-3), 5e-3, 1.0), 30,
            "Static Hertzian press: radius 5 mm, 1 N, no shear; 16x16, pitch 2 mm, "
            "thickness 2 mm (bonded layer, nu 0.5), 1% noise.", seed=1),
        "hertz_shear_turning.npz": _record(
            grid, lambda t: loads.hertz((0.0, 0.0), 5e-3, 1.0, shear_ratio=0.4,
                                        shear_direction=math.remainder(2 * math.pi * t / 2.0, 2 * math.pi)),
            60, "Hertzian press, radius 5 mm, 1 N, shear ratio 0.4 turning once through all "
                "directions in 2 s; 16x16, pitch 2 mm, thickness 2 mm (bonded layer, nu 0.5), 1% noise.",
            seed=2),
        "flat_punch_shear.npz": _record(
            grid, lambda t: loads.flat_punch((-1e-3, 1e-3), 4e-3, 1.5 * _ramp(t), shear_ratio=0.3,
                                             shear_direction=math.radians(30)),
            45, "Flat punch, radius 4 mm, force ramping to 1.5 N, shear ratio 0.3 towards 30 degrees; "
                "16x16, pitch 2 mm, thickness 2 mm (bonded layer, nu 0.5), 1% noise.", seed=3),
        "two_contacts.npz": _record(
            grid, lambda t: [loads.hertz((-7e-3, -5e-3), 3.5e-3, 0.6, shear_ratio=0.3, shear_direction=0.0),
                             loads.hertz((7e-3, 6e-3), 4e-3, 0.8 * _ramp(t),
                                         shear_ratio=0.2, shear_direction=math.radians(120))],
            45, "Two Hertzian contacts (0.6 N with shear 0.3 along +x; 0.8 N ramping, shear 0.2 "
                "towards 120 degrees); 16x16, pitch 2 mm, thickness 2 mm (bonded layer, nu 0.5), 1% noise.",
            seed=4),
        "pinch.npz": _record(
            grid, _scene(grid, "pinch", 1.5), 45,
            "Pinch (tactile-sim --scene pinch, once in 1.5 s): two Hertzian contacts, radius 3.5 mm, "
            "closing from 19.2 to 11 mm apart (centres, along x) and parting again, 0.3 to 0.8 N each, "
            f"shear ratio 0.3 pointing at each other; {skin}", seed=5),
        "three_contacts.npz": _record(
            grid, _scene(grid, "three", 2.0), 60,
            "Three contacts (tactile-sim --scene three, once in 2 s): Hertzian, radius 3 mm, each on its "
            "own path about a home 8 mm from the centre at 90, 210 and 330 degrees: 0.7 N circling with "
            "shear 0.3 along +x; 0.3 to 0.7 N moving in and out with shear 0.2 turning once; 0.8 N moving "
            f"sideways without shear; {skin}", seed=6),
        "twist.npz": _record(
            grid, _scene(grid, "twist", 1.0), 30,
            "Twist (tactile-sim --scene twist, once in 1 s): a 1 N Hertzian press, radius 5 mm, at the "
            "centre, twisted back and forth (torque up to 0.88 mN m, 30% of full slip at friction 0.3) "
            "with no shear: no net tangential force, and the stress is the untwisted press's (torsion is "
            f"invisible to normal-stress sensors); {skin}", seed=7),
        "palm.npz": _record(
            grid, _scene(grid, "palm", 2.0), 60,
            "A fingertip beside a palm (tactile-sim --scene palm, once in 2 s): a 1 N cone, radius 3.5 mm, "
            "circling 1.6 mm about a point 7.2 mm right of the centre with shear ratio 0.3 turning once, and "
            "a flat punch, radius 5 mm, 7.2 mm left of the centre, 0.4 to 0.6 N with shear ratio 0.2 along "
            f"+x: each of the punch's nodes carries about a tenth of the cone's most loaded one; {skin}",
            seed=9),
        "broad_press_32x32.npz": _record(
            large, _scene(large, "press", 6.0), 6,
            "Broad press (tactile-sim --scene press, once in 6 s, one frame a second): a Hertzian press of "
            "semi-axes 30.1 mm over 69% of a 32x32 skin, 14 to 28 N (mean pressure 5 to 10 kPa), no shear; "
            "32x32, pitch 2 mm, thickness 2 mm (bonded layer, nu 0.5), 1% noise.", seed=8, rate=1.0),
    }
    outdir.mkdir(parents=True, exist_ok=True)
    return [save(recording, outdir / name) for name, recording in samples.items()]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("outdir", nargs="?", default=Path(__file__).resolve().parent.parent / "sample_data",
                        type=Path)
    args = parser.parse_args(argv)
    for path in make_all(args.outdir):
        print(path, f"{path.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
