"""Building the solver for the source shown: which kernel and quality preset, and when it still applies.

No Qt. Factoring a geometry is slow, so the window runs :meth:`SolverBuild.build`
in a task and hands the solver to :meth:`SolverBuild.install` when it is done;
every decision around it is made here: a new source of another geometry
drops the quality preset (a preset is measured on the geometry it came with),
a kernel or preset already in use builds nothing, and a rebuild for a source
replaced while it was built is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..sources.source import Source
from .viewer_model import ViewerModel

__all__ = ["SolverBuild"]


@dataclass(frozen=True)
class SolverBuild:
    """A solver to build for ``source``: ``kernel`` and ``configuration`` (a quality preset; None: standard).

    ``rebuild``: ``source`` was already shown when the build was asked for
    (another kernel or quality for it).
    """

    source: Source
    kernel: str
    configuration: object
    rebuild: bool

    @classmethod
    def for_source(cls, model: ViewerModel, source: Source) -> SolverBuild:
        """The solver for a source to show, with the model's kernel and (same geometry) preset."""
        configuration, grid = model.configuration, source.grid
        if model.is_open and grid.key != model.grid.key:
            configuration = None  # a quality preset was measured on the geometry it came with
        return cls(source, model.kernel, configuration, model.source is source)

    @classmethod
    def for_choice(cls, model: ViewerModel, kernel: str, configuration) -> SolverBuild | None:
        """The user picked ``kernel`` or a quality preset: the rebuild of the source shown, or None.

        None when nothing needs building: that kernel and preset are in use,
        or nothing is open (the preset is then kept for the next source).
        """
        if not model.is_open:
            model.configuration = configuration
            return None
        if (kernel, configuration) == (model.kernel, model.configuration):
            return None
        model.configuration = configuration
        return cls(model.source, kernel, configuration, True)

    def build(self):
        """The solver (slow for large grids: run it off the GUI thread)."""
        return ViewerModel.build(self.source.grid, self.kernel, self.configuration)

    def install(self, model: ViewerModel, solver) -> bool:
        """Show the source with ``solver``; False (nothing done) for a rebuild whose source was replaced."""
        if self.rebuild and model.source is not self.source:
            return False  # a rebuild for a source replaced while it was built
        model.configuration = self.configuration
        model.set_source(self.source, solver)
        return True
