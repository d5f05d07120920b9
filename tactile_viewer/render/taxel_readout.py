"""The read-out of one taxel: its number, position, measured stress and force, as one line. No Qt.

The window's hover line (:mod:`tactile_viewer.qt.hover`) shows it for the
taxel under the cursor (:meth:`~tactile_viewer.render.scene.Scene.node_at`).
"""

from __future__ import annotations

import numpy as np

from solver import SensorGrid

from ..model.solved import Solved
from .meshes import MM

__all__ = ["taxel_text"]


def taxel_text(solved: Solved | None, grid: SensorGrid, node: int) -> str:
    """One taxel's read-out: its number, position, measured stress and force.

    Parameters
    ----------
    solved : Solved or None
        The frame shown (None: only where the taxel is).
    grid : SensorGrid
    node : int
        The node index, from 0.

    Returns
    -------
    str
        E.g. ``"taxel 37 (x 5.0 mm, y 3.0 mm): stress 1.23 kPa, Fx +0.12 Fy -0.03 Fz 4.56 mN"``.

    Raises
    ------
    ValueError
        For a node that is not one of the grid's.
    """
    if isinstance(node, bool) or not isinstance(node, (int, np.integer)) or not 0 <= node < grid.size:
        raise ValueError(f"node must be an index from 0 to {grid.size - 1}, got {node!r}")
    x, y = grid.positions[node] * MM
    where = f"taxel {node} (x {x:.1f} mm, y {y:.1f} mm)"
    if solved is None or len(solved.stress) != grid.size:
        return where
    fx, fy, fz = solved.result.forces[node] * 1e3
    return (f"{where}: stress {solved.stress[node] / 1e3:.2f} kPa, "
            f"Fx {fx:+.2f} Fy {fy:+.2f} Fz {fz:.2f} mN")
