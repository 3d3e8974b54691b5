"""``python -m nlp`` runs the ``frf-nlp`` command."""

import sys

from nlp.cli import main

sys.exit(main())
