"""GUI-free numerics of tactile-viewer: contact forces from normal-stress skins.

numpy and scipy only; never imports Qt or pyvista.
"""

from . import efficiency, loads, metrics
from .geometry import SensorGrid
from .inverse import Reconstruction, Reconstructor

__all__ = ["SensorGrid", "Reconstructor", "Reconstruction", "loads", "metrics", "efficiency"]
