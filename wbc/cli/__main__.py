"""``python -m wbc.cli``: the ``wbc`` command."""

import sys

from . import main

sys.exit(main())
