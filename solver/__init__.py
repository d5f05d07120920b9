"""GUI-free numerics of tactile-viewer: contact forces from normal-stress skins.

numpy and scipy only; never imports Qt or pyvista.
"""

from . import efficiency, loads, metrics
from .geometry import SensorGrid
from .inverse import Contact, Reconstruction, Reconstructor
from .quality import Configuration
from .region import RegionSolver, make_solver
from .tracking import ContactTracker as ContactTracker  # re-exported (solver.tracking)

__all__ = ["SensorGrid", "Reconstructor", "RegionSolver", "make_solver", "Configuration", "Reconstruction",
           "Contact", "loads", "metrics", "efficiency"]
