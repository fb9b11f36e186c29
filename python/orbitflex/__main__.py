"""``python -m orbitflex [demo | simulate ...]``: the command line (see ``orbitflex.cli``)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
