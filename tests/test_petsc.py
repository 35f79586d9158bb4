"""The PETSc backends (skfem_rkpm.solvers.petsc): the partition of the rows,
the message without petsc4py, solutions against scipy, the Newton history
of a coarse ring against the default path, and a run on 2 MPI ranks
(``mpiexec -n 2``) against the serial one.

Everything but the partition and the message needs petsc4py (the ``petsc``
extra, a source build: see docs/benchmarks/partitioned.md, "PETSc and MPI") and is
skipped without it; the MPI test also needs ``mpiexec`` of the MPI that
PETSc was built with (``SKFEM_RKPM_MPIEXEC`` overrides the one on PATH).
"""

import csv
import importlib
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from skfem_rkpm.solvers import backend as backend_registry
from skfem_rkpm.solvers import linear as linsolve
from skfem_rkpm.solvers.petsc import bisection, row_owners, world
from skfem_rkpm.solvers.linear import BackendUnavailable, make_solver
from skfem_rkpm.runs.runner import build, run
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

# the coarse ring of tests/test_ring.py in 20 load steps: with 4 or 5 the first
# step takes 13-18 iterations whose contact decisions flip on differences of
# 1e-13 in the solution, and the iteration counts of dense LU and SuperLU differ
RING = ["geometry.divisions=[6,4]", "discretization.support=12.0",
        "discretization.quadrature=4", "steps.count=20", "output.fields=false",
        "output.figures=false"]


def has_petsc():
    try:
        importlib.import_module("petsc4py")
    except ImportError:
        return False
    return True


needs_petsc = pytest.mark.skipif(
    not has_petsc(), reason="petsc4py is not installed (a source build of PETSc with MPI "
                            "and MUMPS: bash .ci/run-mpi, or docs/benchmarks/partitioned.md, "
                            "\"PETSc and MPI\")")


# -- always ------------------------------------------------------------------
@pytest.mark.parametrize("name", ["petsc", "petsc-gamg"])
def test_missing_petsc_names_the_extra_and_the_build(name, monkeypatch):
    real = importlib.import_module

    def fake(mod, *args, **kwargs):
        if mod == "petsc4py":
            raise ImportError("No module named 'petsc4py'")
        return real(mod, *args, **kwargs)

    monkeypatch.setattr(backend_registry.importlib, "import_module", fake)
    with pytest.raises(BackendUnavailable) as err:
        make_solver(name)
    message = str(err.value)
    assert "pip install skfem-rkpm[petsc]" in message
    assert "builds PETSc from source" in message and "mpicc" in message
    assert name not in linsolve.available()


def test_scene_and_command_line_accept_the_petsc_backends():
    for name in ("petsc", "petsc-gamg"):
        scene = load_scene(builtin_scenes()["ring"], [f"steps.solver={name}"])
        assert scene["steps"]["solver"] == name


def test_bisection_balances_the_parts():
    rng = np.random.default_rng(0)
    points = rng.uniform(size=(2, 1000)) * [[3.0], [1.0]]
    for parts in (2, 3, 4, 7):
        owner = bisection(points, parts)
        counts = np.bincount(owner, minlength=parts)
        assert counts.sum() == 1000 and counts.max() - counts.min() <= parts
    owner = bisection(points, 2)  # the first cut is normal to the long side x
    assert points[0, owner == 0].max() <= points[0, owner == 1].min()


def test_rows_of_one_particle_and_its_multipliers_share_a_rank():
    nodes = np.array([[0.0, 1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 0.0]])
    points = np.repeat(nodes, 2, axis=1)  # two dofs per particle, interleaved
    C = sp.csr_matrix(([1.0, 0.5], ([0, 1], [7, 0])), shape=(2, 8))
    A = sp.bmat([[sp.identity(8), C.T], [C, None]]).tocsr()
    owner = row_owners(A, 2, points)
    np.testing.assert_array_equal(owner[:8], [0, 0, 0, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(owner[8:], [1, 0])  # owners of dofs 7 and 0
    np.testing.assert_array_equal(row_owners(A, 2), [0] * 5 + [1] * 5)  # no points: blocks


def test_world_is_serial_without_a_launcher(monkeypatch):
    for key in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"):
        monkeypatch.delenv(key, raising=False)
    assert world() == (0, 1)
    monkeypatch.setenv("PMI_SIZE", "2")
    monkeypatch.setenv("PMI_RANK", "1")
    assert world() == (1, 2)


# -- with petsc4py ------------------------------------------------------------
def random_system(symmetric, n=600, seed=1):
    rng = np.random.default_rng(seed)
    R = sp.random(n, n, density=0.01, random_state=rng, format="csr")
    A = R @ R.T + sp.identity(n) * 0.5 if symmetric else R + sp.identity(n) * 2.0
    return A.tocsr(), rng.normal(size=n)


@needs_petsc
@pytest.mark.parametrize("name", ["petsc", "petsc-gamg"])
@pytest.mark.parametrize("symmetric", [True, False])
def test_petsc_solves_sparse_systems(name, symmetric):
    A, b = random_system(symmetric)
    points = np.random.default_rng(2).uniform(size=(2, A.shape[0]))
    solver = make_solver(name, points=points)
    x = solver.factor(A).solve(b)
    ref = spsolve(A.tocsc(), b)
    assert np.linalg.norm(x - ref) <= 1e-10 * np.linalg.norm(ref)
    # new values, same pattern: the analysis is kept
    x = solver.factor(A * 2.0).solve(b)
    assert np.linalg.norm(2 * x - ref) <= 1e-10 * np.linalg.norm(ref)
    assert solver.stats["analyses"] == 1 and solver.stats["factorizations"] == 2
    assert "PETSc" in solver.describe() and "1 process" in solver.describe()


@needs_petsc
def test_petsc_solves_the_saddle_point_system():
    from test_linsolve import system

    from skfem_rkpm.solvers.constrained import solve_constrained

    K, C, g, f = system("rk")
    d_ref, lam_ref = solve_constrained(K, f, C, g, solver="dense")
    for name in ("petsc", "petsc-gamg"):
        d, lam = solve_constrained(K, f, C, g, solver=name)
        assert np.linalg.norm(d - d_ref) <= 1e-9 * np.linalg.norm(d_ref), name
        assert np.linalg.norm(lam - lam_ref) <= 1e-8 * np.linalg.norm(lam_ref), name


def ring_history(solver):
    scene = load_scene(builtin_scenes()["ring"], [*RING, f"steps.solver={solver}"])
    sim = build(scene)
    result = run(sim, progress=False)
    assert result.completed, result.message
    return result


def history_difference(result, reference):
    """Largest differences of the relative residuals of every iteration and
    of the solutions of every step (relative to their largest value)."""
    assert [r.iterations for r in result.history] == [r.iterations for r in reference.history]
    residuals = max(np.abs(np.subtract(a.residuals, b.residuals)).max()
                    for a, b in zip(result.history, reference.history))
    solutions = max(np.abs(a - b).max() / np.abs(b).max()
                    for a, b in zip(result.solutions, reference.solutions))
    return residuals, solutions


@needs_petsc
def test_ring_newton_history_is_the_default_one():
    """Against the default path (dense LU at this size).  The relative
    residuals of the iterations agree to 3e-10, not 1e-10: SuperLU differs
    from dense LU by as much (measured 2.6e-10 each), since the residual after
    a Newton correction is a difference of contact penalty forces about 1e5
    times larger; the solutions agree to 4e-14."""
    reference = ring_history("auto")
    residuals, solutions = history_difference(ring_history("petsc"), reference)
    assert residuals <= 1e-9 and solutions <= 1e-12
    superlu, _ = history_difference(ring_history("superlu"), reference)
    assert residuals <= 3 * superlu + 1e-10  # as close as the serial sparse solver


def mpiexec():
    return os.environ.get("SKFEM_RKPM_MPIEXEC") or shutil.which("mpiexec")


def mpi_environment():
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    # Open MPI refuses to start as root without these
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT", "1")
    env.setdefault("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
    return env


def read_history(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def launcher(ranks):
    """``mpiexec -n ranks`` (Open MPI: ``--oversubscribe`` for more ranks than cores)."""
    version = subprocess.run([mpiexec(), "--version"], capture_output=True, text=True)
    text = version.stdout + version.stderr
    extra = ["--oversubscribe"] if "Open MPI" in text or "OpenRTE" in text else []
    return [mpiexec(), *extra, "-n", str(ranks)]


@needs_petsc
@pytest.mark.skipif(mpiexec() is None, reason="no mpiexec on PATH")
@pytest.mark.parametrize("ranks", [2, 4])
def test_mpi_ranks_give_the_serial_history_and_fields(tmp_path, ranks):
    """The ring partitioned over 2 and 4 ranks (4 oversubscribe 2 cores):
    each rank integrates its own cells (solvers.partitioned), and the
    history, the fields written and the checkpoint are those of the serial
    run to the solver's round-off; the run folders hold the same files."""
    import h5py

    env = mpi_environment()
    probe = subprocess.run([*launcher(ranks), sys.executable, "-c",
                            "from petsc4py import PETSc; print(PETSc.COMM_WORLD.getSize())"],
                           capture_output=True, text=True, env=env, timeout=120)
    # the ranks' lines may interleave: compare the characters printed
    if probe.returncode != 0 or "".join(probe.stdout.split()) != str(ranks) * ranks:
        pytest.skip(f"{mpiexec()} does not start PETSc on {ranks} ranks (another MPI than "
                    f"PETSc's? set SKFEM_RKPM_MPIEXEC): {probe.stdout!r} {probe.stderr[-500:]!r}")
    # figures too: rank 0 alone makes them after the run, which must not
    # leave the other ranks waiting on a collective PETSc clean-up
    settings = [arg for s in RING + ["output.fields=true", "output.every=10",
                                     "output.figures=true"]
                for arg in ("--set", s)]
    command = [sys.executable, "-m", "skfem_rkpm.runs.cli", "run", "ring", *settings, "--quiet"]
    # serial: the default path (dense LU at this size)
    serial = subprocess.run([*command, "--out", str(tmp_path / "serial")],
                            capture_output=True, text=True, env=env, timeout=600)
    assert serial.returncode == 0, serial.stderr
    parallel = subprocess.run([*launcher(ranks), *command, "--solver", "petsc",
                               "--out", str(tmp_path / "mpi")],
                              capture_output=True, text=True, env=env, timeout=900)
    assert parallel.returncode == 0, parallel.stdout + parallel.stderr
    assert parallel.stdout.count("completed") == 1  # only rank 0 prints
    assert ({p.name for p in (tmp_path / "mpi").iterdir()}
            == {p.name for p in (tmp_path / "serial").iterdir()})
    for name in ("step-000010.h5", "step-000020.h5"):
        with h5py.File(tmp_path / "mpi" / "fields" / name) as got, \
                h5py.File(tmp_path / "serial" / "fields" / name) as want:
            for key in want:
                scale = max(np.abs(want[key][()]).max(), 1.0)
                np.testing.assert_allclose(got[key][()], want[key][()], rtol=0,
                                           atol=1e-8 * scale, err_msg=f"{name}: {key}")
    # a resumed partitioned run (here: nothing left to do) restores every
    # rank's points and makes the figures from the checkpoint's state
    resumed = subprocess.run([*launcher(ranks), *command, "--solver", "petsc",
                              "--out", str(tmp_path / "mpi"), "--resume"],
                             capture_output=True, text=True, env=env, timeout=900)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert resumed.stdout.count("completed") == 1
    mpi_state = np.load(tmp_path / "mpi" / "checkpoint.npz")
    serial_state = np.load(tmp_path / "serial" / "checkpoint.npz")
    for key in ("d", "alpha", "Cp_inv"):
        np.testing.assert_allclose(mpi_state[key], serial_state[key], rtol=0,
                                   atol=1e-9 * max(np.abs(serial_state[key]).max(), 1e-3))
    rows = read_history(tmp_path / "mpi" / "history.csv")
    ref = read_history(tmp_path / "serial" / "history.csv")
    assert len(rows) == len(ref) >= 20 and rows[0].keys() == ref[0].keys()
    assert ({p.name for p in (tmp_path / "mpi").iterdir()}
            == {p.name for p in (tmp_path / "serial").iterdir()})
    for row, expected in zip(rows, ref):
        assert row["iterations"] == expected["iterations"]
        for key in row:
            value, wanted = float(row[key]), float(expected[key])
            if key == "seconds":
                continue
            if key == "residual":  # the final relative residual, at its noise floor
                assert abs(value - wanted) <= 1e-9, key
            elif key.startswith("reaction platen"):
                # penalty forces: k_N times a penetration of ~1e-5 of the
                # displacements; measured 6e-10 between SuperLU and dense LU
                # too, and between 2 ranks and dense LU
                assert abs(value - wanted) <= 2e-9 * abs(wanted), key
            else:  # positions, penetration, the symmetry plane's reaction
                assert abs(value - wanted) <= 1e-10 * max(abs(wanted), 1.0), key
