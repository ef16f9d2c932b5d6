"""swarmplan: plan and simulate 3D flight for many UAVs among static and moving obstacles."""

__version__ = "0.1.0"
