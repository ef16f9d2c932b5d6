"""Sweeps: Monte-Carlo studies of worlds x optimizers x seeds x parameter overrides on
``dask.distributed``, from one laptop (a LocalCluster) to a cluster (any scheduler address).

``python -m swarmplan.sweep SPEC.yaml`` (see :mod:`swarmplan.cli.sweep` and docs/sweeps.md).
"""

from swarmplan.sweep.engine import columns, make_client, metrics_row, run_task, run_tasks
from swarmplan.sweep.spec import Spec, SpecError, Task, load_spec, parse_spec

__all__ = [
    "Spec",
    "SpecError",
    "Task",
    "columns",
    "load_spec",
    "make_client",
    "metrics_row",
    "parse_spec",
    "run_task",
    "run_tasks",
]
