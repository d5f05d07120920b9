"""tactile-viewer: the desktop application over the :mod:`solver` package.

Laid out by what each part does, each folder importing only those below it
(``docs/architecture.md``; an import-linter ``layers`` contract checks it):

- :mod:`tactile_viewer.cli`: the commands (``tactile-viewer``, ``tactile-record``,
  ``tactile-sim``, ``tactile-tradeoff``);
- :mod:`tactile_viewer.qt`: the window, its panels, dialogs and menus;
- :mod:`tactile_viewer.render`: the 3-D scene and movies, pyvista alone (no Qt);
- :mod:`tactile_viewer.model`: the viewer's state, its solves and the time series (no Qt);
- :mod:`tactile_viewer.sources`: where frames come from, recordings and live boards (no Qt);
- :mod:`tactile_viewer.io`: the file formats (no Qt).
"""
