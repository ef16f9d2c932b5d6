"""``python -m swarmplan.run``: the command line lives in :mod:`swarmplan.cli.run`."""

import sys

from swarmplan.cli.run import main

if __name__ == "__main__":
    sys.exit(main())
