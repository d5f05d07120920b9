"""``python -m tactile_viewer``: the ``tactile-viewer`` command (:mod:`tactile_viewer.cli.tactile_viewer`)."""

import sys

from .cli.tactile_viewer import main

if __name__ == "__main__":
    sys.exit(main())
