"""``python -m swarmplan.compare``: the command line lives in :mod:`swarmplan.cli.compare`."""

import sys

from swarmplan.cli.compare import main

if __name__ == "__main__":
    sys.exit(main())
