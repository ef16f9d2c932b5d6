"""One BLAS thread for swarmplan's small matrices.

swarmplan multiplies small matrices (CFO's 100 x 50 probe Gram matrix, rotations of a few
hundred points). A multithreaded BLAS splits even these across threads, and when the other
cores are busy (a Dask sweep with one worker per core, or any other process) its threads
wait for each other: on the 2-core development machine, with the second core busy,
``U @ U.T`` for a 100 x 50 ``U`` took 502 µs with OpenBLAS's 2 threads and 23 µs with one.
The command-line programs and sweep workers therefore run BLAS on one thread; library users
who want the same call :func:`limit_blas_threads` once (it changes the whole process).
"""

from __future__ import annotations

import os

#: the variables BLAS libraries read when they load (OpenBLAS, MKL, BLIS, and OpenMP builds)
_ENV = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS", "OMP_NUM_THREADS")


def limit_blas_threads(threads: int = 1) -> None:
    """Run BLAS on ``threads`` threads in this process and the processes it starts.

    Libraries already loaded are limited through threadpoolctl; libraries loaded later (scipy
    brings its own OpenBLAS) and child processes (Dask workers) read the environment
    variables set here. A thread count the user chose in the environment is left alone.
    """
    if any(var in os.environ for var in _ENV):
        return
    for var in _ENV:
        os.environ[var] = str(threads)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads, user_api="blas")
