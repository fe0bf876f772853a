"""``python -m hierplan_opt`` runs the ``hierplan`` command line."""

import sys

from hierplan_opt.cli import main

sys.exit(main())
