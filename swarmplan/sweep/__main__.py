"""``python -m swarmplan.sweep``: the command line lives in :mod:`swarmplan.cli.sweep`."""

import sys

from swarmplan.cli.sweep import main

sys.exit(main())
