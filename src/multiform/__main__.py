"""``python -m multiform``: the ``multiform`` command."""

import sys

from .cli import main

sys.exit(main())
