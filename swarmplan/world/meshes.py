"""Mesh obstacles' geometry read from their files (any format trimesh reads)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from swarmplan.world.checker import Checker


def load_mesh(c: Checker, path: str, file: str, base_dir: Path, scale: np.ndarray) -> tuple | None:
    fp = (base_dir / file).resolve()
    if not fp.is_file():
        c.add(f"{path}.file", f"mesh file not found: {fp}")
        return None
    import trimesh  # here, not at import: ~0.5 s of start-up that worlds without meshes never need

    try:
        mesh = trimesh.load(str(fp), force="mesh")
    except Exception as exc:  # trimesh raises many kinds; all mean "cannot read"
        c.add(f"{path}.file", f"cannot read mesh {fp}: {exc}")
        return None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        c.add(f"{path}.file", f"{fp} holds no triangles")
        return None
    return np.asarray(mesh.vertices, dtype=float) * scale, np.asarray(mesh.faces, dtype=np.int64)
