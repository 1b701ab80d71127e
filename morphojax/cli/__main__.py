"""`python -m morphojax.cli ...`, the same as the `morphojax` console script."""

import sys

from . import main

sys.exit(main())
