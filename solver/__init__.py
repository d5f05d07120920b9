"""GUI-free numerics of tactile-viewer: contact forces from normal-stress skins.

numpy and scipy only; never imports Qt or pyvista. :class:`Reconstructor` is
the one way to a solver, for a skin of any size and any quality setting.
"""

from . import efficiency, loads, metrics
from .geometry import SensorGrid
from .quality import Configuration
from .reconstructor import Reconstructor
from .results import Contact, Reconstruction
from .tracking import ContactTracker as ContactTracker  # re-exported (solver.tracking)

__all__ = ["SensorGrid", "Reconstructor", "Configuration", "Reconstruction", "Contact", "loads", "metrics",
           "efficiency"]
