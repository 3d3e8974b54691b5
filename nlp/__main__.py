"""``python -m nlp`` runs the ``frf-nlp`` command."""

import sys

from .cli import main

sys.exit(main())
