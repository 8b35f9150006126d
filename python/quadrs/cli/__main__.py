"""``python -m quadrs.cli``: the command line."""

import sys

from quadrs.cli.main import main

sys.exit(main())
