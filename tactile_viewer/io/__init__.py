"""File formats (no Qt): recordings (NPZ, CSV, MCAP), sensor layouts, force exports, sidecars.

:func:`tactile_viewer.io.files.load` reads every recording format."""
