"""``python -m sprayplan`` runs the command line."""

import sys

from sprayplan.cli import main

sys.exit(main())
