"""A run's folds per step (history.csv) and at its end (final message, stop
report): the drawn cells and the deformation map itself, checked against
an independent evaluation of the map (central differences of the field's
values, ``basis.probes``)."""

import csv
import re

import numpy as np
import pytest

import skfem_rkpm.runs.runner as runner
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.fold_report import map_check
from skfem_rkpm.runs.io import corner_jacobians, nodal_displacements
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

COARSE = ["geometry.divisions=[6,4]", "output.fields=false", "output.figures=false"]


def ring(settings):
    return load_scene(builtin_scenes()["ring"], COARSE + settings)


def det_by_differences(basis, d, X, h=1e-5):
    """``det F`` of the axisymmetric map at ``X`` from the displacements at
    X ± h e_k (second order in h) and the hoop stretch ``1 + u_r/R``."""
    X = np.asarray(X, float)
    shifts = np.array([X + s * h * e for e in np.eye(2) for s in (1, -1)]).T
    u = (basis.probes(np.column_stack([X, shifts])) @ d).reshape(2, -1)
    grad = np.column_stack([(u[:, 1 + 2 * k] - u[:, 2 + 2 * k]) / (2 * h) for k in range(2)])
    F = np.eye(2) + grad
    return np.linalg.det(F) * (1 + u[0, 0] / X[0])


def test_history_counts_the_folded_cells_of_every_step(tmp_path):
    """The stick ring on 6 x 4 cells to 40 % in 4 steps: every row has the
    drawn cells folded, the map's folded cells and its smallest det F, the
    last row those of the final state (counted again here, and the smallest
    det F found again by differences at its point)."""
    sim = runner.build(ring(["tools.platen.friction=stick", "tools.platen.motion=[0.0,-8.0]",
                             "steps.count=4"]), "rkpm")
    result = runner.run(sim, tmp_path, progress=False)
    assert result.completed
    rows = list(csv.DictReader(open(tmp_path / "history.csv", newline="")))
    assert len(rows) == len(result.history) >= 4
    for row in rows:
        assert int(row["drawn folded cells"]) >= 0 and int(row["map folded cells"]) >= 0
        assert 0.0 < float(row["map det F min"]) <= 1.0  # compressed, valid
    J = corner_jacobians(sim.mesh, nodal_displacements(sim.basis, result.d))
    assert int(rows[-1]["drawn folded cells"]) == int((J <= 0).any(axis=1).sum())
    check = map_check(sim, result.d)
    assert float(rows[-1]["map det F min"]) == check.min_det
    assert check.min_det == pytest.approx(det_by_differences(sim.basis, result.d, check.X),
                                          rel=1e-6)


def test_a_final_state_names_whether_the_map_folds(tmp_path):
    """The coefficients of the outer top corner particle moved by (-8, -8)
    mm: its drawn cell folds; the message says so and what the RK map does,
    with the smallest det F it found, which the differences confirm."""
    sim = runner.build(ring([]), "rkpm")
    corner = int(np.flatnonzero((sim.mesh.p[0] == 60) & (sim.mesh.p[1] == 20))[0])
    d = np.zeros(sim.basis.N)
    d[2 * corner:2 * corner + 2] = [-8.0, -8.0]
    J = corner_jacobians(sim.mesh, nodal_displacements(sim.basis, d))
    message = runner.final_state_message(sim, d)
    assert message.startswith(f"completed with inverted cells: det F = {J.min():.3g} <= 0 at "
                              f"the corner X = (60, 20)")
    assert f"({int((J <= 0).any(axis=1).sum())} of 24 cells folded)" in message
    found = re.search(r"the RK map itself (folds|is valid): .*?det F (?:=|>=) ([-\d.e+]+) at "
                      r"(?:all \d+ sample points \(25 in each of 24 cells; smallest at )?"
                      r"X = \(([-\d.e+]+), ([-\d.e+]+)\)", message)
    assert found, message
    X = [float(found[3]), float(found[4])]
    value = det_by_differences(sim.basis, d, X)
    assert float(found[2]) == pytest.approx(value, rel=5e-3)  # 3 significant digits printed
    assert (found[1] == "folds") == (value <= 0)
    if found[1] == "folds":
        assert message.endswith("use more load steps, a finer mesh or another discretization")
        dynamic = runner.final_state_message(sim, d, "a smaller dynamics.time_step")
        assert dynamic.endswith("use a smaller dynamics.time_step, a finer mesh or another "
                                "discretization")
    else:
        assert message.endswith("only the drawn cells fold")


def test_a_stop_report_names_the_newton_iterations_on_the_console(tmp_path, capsys):
    """Newton allowed 2 iterations: the console names steps.max_iterations
    with the value used, and the state it stopped in (at rest: nothing
    folded, the map's det F = 1)."""
    code = main(["run", "ring", "--quiet", "--out", str(tmp_path / "r"),
                 *[f"--set={s}" for s in COARSE + ["steps.count=2", "steps.max_iterations=2",
                                                   "steps.max_cutbacks=0"]]])
    assert code == 1
    err = capsys.readouterr().err
    assert "more Newton iterations a step (--set steps.max_iterations=4; this run allowed 2)" \
        in err
    assert re.search(r"last converged state: no drawn cell folded \(of 24\); the RK map "
                     r"itself is valid: det F >= 1 at all 600 sample points", err), err
    status = (tmp_path / "r" / "status.txt").read_text()
    assert "--set steps.max_iterations=4; this run allowed 2" in status
