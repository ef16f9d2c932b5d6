"""``python -m swarmplan.bench``: the command line lives in :mod:`swarmplan.cli.bench`."""

import sys

from swarmplan.cli.bench import main

if __name__ == "__main__":
    sys.exit(main())
