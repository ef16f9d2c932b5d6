"""``python -m swarmplan.replay``: the command line lives in :mod:`swarmplan.cli.replay`."""

import sys

from swarmplan.cli.replay import main

sys.exit(main())
