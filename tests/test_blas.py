"""The command-line programs run BLAS on one thread (swarmplan/blas.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np  # noqa: F401 - loads the BLAS library that threadpoolctl reports
import pytest

from swarmplan.runtime.blas import limit_blas_threads


def test_limit_blas_threads_sets_every_blas_library_to_one_thread(monkeypatch) -> None:
    from threadpoolctl import threadpool_info, threadpool_limits

    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS", "OMP_NUM_THREADS"):
        monkeypatch.delenv(var, raising=False)
    blas = [i for i in threadpool_info() if i["user_api"] == "blas"]
    if not blas:
        pytest.skip("numpy has no BLAS library that threadpoolctl can see")
    before = max(i["num_threads"] for i in blas)
    try:
        limit_blas_threads(1)
        assert all(i["num_threads"] == 1 for i in threadpool_info() if i["user_api"] == "blas")
    finally:
        threadpool_limits(limits=before, user_api="blas")
        for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS", "OMP_NUM_THREADS"):
            monkeypatch.delenv(var, raising=False)


def test_run_cli_limits_blas_before_simulating(tmp_path) -> None:
    # the CLI's own entry point, in a fresh interpreter: threads as the CLI leaves them
    code = (
        "import sys; from threadpoolctl import threadpool_info; import swarmplan.cli.run as r; "
        "r.main(['worlds/quickstart.yaml', '--max-time', '0.2', '--out', sys.argv[1]]); "
        "print(max([i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'] or [1]))"
    )
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "q.mcap")],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    assert out.stdout.strip().splitlines()[-1] == "1", out.stdout + out.stderr
