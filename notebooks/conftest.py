"""The test suite runs the notebooks at their smoke-test size (one knob, read by every notebook)."""

import os

os.environ.setdefault("MORPHOJAX_NOTEBOOK_SIZE", "small")
