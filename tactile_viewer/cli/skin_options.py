"""The options that describe a regular skin on the command line, for the commands that make one.

``tactile-sim`` and ``tactile-tradeoff`` take the same geometry: taxels along x
and y, pitch, layer thickness, the elastomer's Poisson ratio and the taxel size.
"""

from __future__ import annotations

import argparse

from solver import SensorGrid

__all__ = ["add_skin_arguments", "skin_grid"]


def add_skin_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--nx``, ``--ny``, ``--pitch``, ``--thickness``, ``--poisson-ratio`` and ``--sensor-size``."""
    parser.add_argument("--nx", type=int, default=16, help="taxels along x (default 16)")
    parser.add_argument("--ny", type=int, default=16, help="taxels along y (default 16)")
    parser.add_argument("--pitch", type=float, default=2e-3, help="metres")
    parser.add_argument("--thickness", type=float, default=2e-3, help="metres")
    parser.add_argument("--poisson-ratio", type=float, default=0.5,
                        help="Poisson ratio nu of the elastomer, in [0, 0.5] (default 0.5: incompressible)")
    parser.add_argument("--sensor-size", type=float, default=0.0,
                        help="side of a square taxel, metres, at most the pitch (default 0: point sensors)")


def skin_grid(parser: argparse.ArgumentParser, args: argparse.Namespace) -> SensorGrid:
    """The skin the options describe; a geometry :class:`~solver.SensorGrid` refuses ends the command
    with its reason (``parser.error``, exit status 2)."""
    try:
        return SensorGrid.regular(args.nx, args.ny, args.pitch, args.thickness,
                                  poisson_ratio=args.poisson_ratio, sensor_size=args.sensor_size)
    except ValueError as exc:
        parser.error(str(exc))
