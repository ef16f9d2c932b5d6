"""``python -m swarmplan.track``: the command line lives in :mod:`swarmplan.cli.track`."""

import sys

from swarmplan.cli.track import main

sys.exit(main())
