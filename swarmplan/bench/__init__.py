"""Benchmarks of the optimizer library: ``python -m swarmplan.bench {optimizers,overhead} ...``.

``functions`` holds vectorized benchmark functions; ``optimizers`` runs the paper suites;
``overhead`` measures the library's own per-evaluation cost.
"""
