import sys

from swarmplan.sweep.cli import main

sys.exit(main())
