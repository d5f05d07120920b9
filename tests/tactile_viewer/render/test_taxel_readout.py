"""One taxel's read-out: its number, position, measured stress and force."""

import pytest

from tactile_viewer.model.solved import Solved
from tactile_viewer.render.taxel_readout import taxel_text
from tests.tactile_viewer.render.hertz_frames import MM


def test_taxel_text_names_the_taxel_and_its_values(regular_frame):
    grid, stress, result = regular_frame
    solved = Solved.of(grid, stress, result)
    node = 13
    text = taxel_text(solved, grid, node)
    x, y = grid.positions[node] * MM
    fx, fy, fz = result.forces[node] * 1e3
    assert text == (f"taxel 13 (x {x:.1f} mm, y {y:.1f} mm): stress {stress[node] / 1e3:.2f} kPa, "
                    f"Fx {fx:+.2f} Fy {fy:+.2f} Fz {fz:.2f} mN")
    assert taxel_text(None, grid, node) == f"taxel 13 (x {x:.1f} mm, y {y:.1f} mm)"
    for bad in (-1, grid.size, 2.0, True):
        with pytest.raises(ValueError, match=rf"node must be an index from 0 to {grid.size - 1}, got {bad!r}"):
            taxel_text(solved, grid, bad)
