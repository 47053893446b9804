"""``python -m dropfit``: the same as the ``dropfit`` console script."""

import sys

from .cli import main

sys.exit(main())
