"""``python -m swarmplan.export RUN.mcap --format crazyflie|px4|csv --out DIR [--check]``."""

import sys

from swarmplan.cli.export import main

sys.exit(main())
