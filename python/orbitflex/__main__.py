"""``python -m orbitflex [demo | simulate ...]``."""

import sys

from .cli import main

sys.exit(main())
