"""Command-line programs (``python -m swarmplan.run`` is :mod:`swarmplan.cli.run`)."""
