"""One solve as the model stood when it was asked for: the frame, the solver and the parameters.

No Qt. The :class:`~tactile_viewer.model.viewer_model.ViewerModel` makes a
:class:`SolveJob` for each change that alters what is shown and runs it here
and now (:meth:`~tactile_viewer.model.viewer_model.ViewerModel.solve`) or on its
worker thread; :meth:`SolveJob.run` touches nothing of the model.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .solved import Solved

__all__ = ["SolveJob"]


@dataclass(frozen=True)
class SolveJob:
    """One solve as the model stood when it was asked for.

    ``generation`` is the model's count of installed solvers: a result of an
    older one is dropped.
    """

    generation: int
    solver: object
    frame: int
    time: float
    stress: np.ndarray
    auto: bool
    shear_ratio: float
    shear_direction: float

    def run(self) -> Solved:
        """Reconstruct the frame (Auto, or with the manual parameters), timed."""
        start = time.perf_counter()
        if self.auto:
            result = self.solver.solve(self.stress)
        else:
            result = self.solver.solve(self.stress, shear_ratio=self.shear_ratio,
                                       shear_direction=self.shear_direction)
        elapsed = 1e3 * (time.perf_counter() - start)
        return Solved.of(self.solver.grid, self.stress, result, frame=self.frame, time=self.time,
                         solve_ms=elapsed, auto=self.auto)
