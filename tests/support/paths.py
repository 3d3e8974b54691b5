"""Where the repository and its committed cases are (tests/data/README.md lists what the
tests read from them)."""

import os

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))  # the repository
CASES = os.path.join(ROOT, "cases")
