"""``python -m train.cli ...``: the ``ecorl`` command line."""

import sys

from train.cli import main

sys.exit(main())
