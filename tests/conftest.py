import os

# one BLAS thread: small dense solves are 100x slower when OpenBLAS threads
# compete with other processes for the 2 cores, and timings get noisy
for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

from contextlib import contextmanager

import numpy as np
import pytest
from skfem import MeshQuad, MeshTri


def perturbed(mesh, amplitude, seed=0):
    """Move interior vertices randomly by up to ``amplitude`` x the spacing."""
    rng = np.random.default_rng(seed)
    p = mesh.p.copy()
    inner = ~np.isin(np.arange(mesh.nvertices), mesh.boundary_nodes())
    h = np.diff(np.unique(mesh.p[0]))[0]
    p[:, inner] += amplitude * h * rng.uniform(-1, 1, (2, inner.sum()))
    return type(mesh)(p, mesh.t).with_defaults()


@pytest.fixture
def distorted_quads():
    t = np.linspace(0.0, 1.0, 11)
    return perturbed(MeshQuad.init_tensor(t, t), 0.3)


@pytest.fixture
def distorted_tris():
    t = np.linspace(0.0, 1.0, 11)
    return perturbed(MeshTri.init_tensor(t, t), 0.3)


@contextmanager
def interrupted_at_checkpoint(monkeypatch, call=3):
    """Inside the block the runner's ``call``-th checkpoint raises
    KeyboardInterrupt instead of being written (a kill after that step)."""
    import skfem_rkpm.runs.runner as runner

    write = runner.save_checkpoint
    calls = {"n": 0}

    def interrupting(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == call:
            raise KeyboardInterrupt
        return write(*args, **kwargs)

    monkeypatch.setattr(runner, "save_checkpoint", interrupting)
    try:
        yield
    finally:
        monkeypatch.setattr(runner, "save_checkpoint", write)
