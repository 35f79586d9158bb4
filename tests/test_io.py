"""History CSV and XDMF fields round trip."""

import csv

import meshio
import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector

from skfem_rkpm import RKBasis
from skfem_rkpm.runs.io import FieldWriter, cell_averages, nodal_displacements, write_history
from skfem_rkpm.meshes import rectangle
from skfem_rkpm.mechanics.materials import J2Material, perfect
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.solvers.newton import Prescribed, newton_steps


@pytest.mark.parametrize("kind", ["rk", "fem"])
def test_history_and_fields_round_trip(tmp_path, kind):
    mesh = rectangle(1.0, 1.0, 3, 3)
    basis = (RKBasis(mesh, vector=True) if kind == "rk"
             else Basis(mesh, ElementVector(ElementQuad1()), intorder=2))
    problem = SolidProblem(basis, J2Material(200e3, 0.3, perfect(300.0)))
    conditions = [Prescribed("bottom", 1, 0.0, "weak"), Prescribed("left", 0, 0.0, "weak"),
                  Prescribed("top", 1, -0.1, "weak")]
    path = tmp_path / "fields.xdmf"
    with FieldWriter(path, problem) as fields:
        result = newton_steps(problem, conditions, steps=3)
        fields.write(1.0, result.d)
    write_history(tmp_path / "history.csv", result.history,
                  extra=[{"height": 1 - 0.1 * r.t} for r in result.history])
    rows = list(csv.DictReader(open(tmp_path / "history.csv")))
    assert len(rows) == 3 and float(rows[-1]["t"]) == pytest.approx(1.0)
    assert float(rows[-1]["height"]) == pytest.approx(0.9)
    assert float(rows[-1]["reaction top[1]"]) == pytest.approx(
        result.history[-1].reactions["top[1]"])
    with meshio.xdmf.TimeSeriesReader(str(path)) as reader:
        points, cells = reader.read_points_cells()
        t, point_data, cell_data = reader.read_data(0)
    u = point_data["displacement"]
    # homogeneous compression: top vertices moved by -0.1, bottom by 0
    np.testing.assert_allclose(u[np.isclose(points[:, 1], 1.0), 1], -0.1, atol=1e-10)
    np.testing.assert_allclose(u[np.isclose(points[:, 1], 0.0), 1], 0.0, atol=1e-10)
    np.testing.assert_allclose(u, np.c_[nodal_displacements(basis, result.d), np.zeros(16)])
    # the yield condition holds for the Kirchhoff stress τ = J σ
    J = np.linalg.det(problem.evaluate(result.d, tangent=False).F)
    np.testing.assert_allclose(cell_data["von_mises"][0] * J[0], 300.0, rtol=1e-8)
    assert cell_data["plastic_strain"][0].min() > 0.05


def test_cell_averages_weigh_by_volume():
    dx = np.array([[1.0, 3.0]])
    assert cell_averages(np.array([2.0, 6.0]), dx)[0] == pytest.approx(5.0)
