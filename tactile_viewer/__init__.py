"""tactile-viewer: the desktop application over the :mod:`solver` package.

Until the Qt window lands, the command line (``python -m tactile_viewer``)
reconstructs recordings headlessly and prints a per-frame report.
"""
