"""A worker plugin of the sweep's local cluster: its workers ignore SIGINT and keep quiet
about a scheduler that goes away.

A Ctrl-C in a terminal reaches the whole process group; the sweep's own process answers it
(it closes the cluster and keeps every finished row), the workers must not each print a
traceback. Workers started with the cluster inherit an ignored SIGINT; this plugin covers the
ones a nanny restarts later. When the cluster closes under a busy worker, its heartbeat to
the scheduler fails and ``distributed.worker`` logs that as an ERROR with a traceback: a
worker's own log is only about its connection (a run's failure comes back as its row's
``error``, a worker's death is reported by the scheduler), so it is raised to CRITICAL.
"""

from __future__ import annotations

import logging
import signal
import threading

from distributed.diagnostics.plugin import WorkerPlugin


class IgnoreSigint(WorkerPlugin):
    """On each worker: SIGINT ignored (main thread), connection errors not logged."""

    def setup(self, worker) -> None:  # noqa: ANN001 - distributed.Worker
        logging.getLogger("distributed.worker").setLevel(logging.CRITICAL)
        logging.getLogger("distributed.core").setLevel(logging.CRITICAL)
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
