"""``python -m mitlc``: the same command as ``mitlc``.

Python puts the current directory first on ``sys.path`` for ``-m``; it is taken off, so that
the command finds modules as the ``mitlc`` script does (a world file's modules are also refused
from the current directory by their origin: :mod:`mitlc.worlds.trust`)."""

import os
import sys

if sys.path and sys.path[0] in ("", os.getcwd()):
    del sys.path[0]

from mitlc.cli import main

if __name__ == "__main__":
    main()
