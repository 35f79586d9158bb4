"""Results on disk: step history as CSV, fields as an XDMF time series.

The XDMF file (with its HDF5 companion, written by meshio) opens in ParaView:
nodal displacements as point data (use *Warp By Vector*), cell averages of
the quadrature-point state (Cauchy stress, equivalent plastic strain) as
cell data.  For RK bases the nodal displacements are the nodal values
``Λᵀ d`` (Eq. 3.32), not the coefficients.
"""

import csv
import os
from pathlib import Path

import meshio
import numpy as np

__all__ = ["nodal_displacements", "cell_averages", "write_history", "FieldWriter"]

MESHIO_CELLS = {"MeshTri1": "triangle", "MeshQuad1": "quad", "MeshTet1": "tetra",
                "MeshHex1": "hexahedron", "MeshLine1": "line"}


def nodal_displacements(basis, d):
    """Displacement of every mesh vertex, shape (nvertices, dim)."""
    nv, ncomp = basis.mesh.nvertices, basis.mesh.dim()
    if hasattr(basis, "nodal_values"):
        values = basis.nodal_values(d).reshape(-1, ncomp)
        if values.shape[0] != nv:
            raise ValueError("particles are not the mesh vertices; probe the "
                             "field with basis.probes(mesh.p) instead")
        return values
    return np.asarray(d)[: ncomp * nv].reshape(nv, ncomp)  # vertex dofs come first


def cell_averages(values, dx):
    """Volume averages per cell of point values (n, ...) on a (nelems, nqp) rule."""
    nelems, nqp = dx.shape
    v = np.asarray(values).reshape((nelems, nqp) + np.shape(values)[1:])
    w = dx / dx.sum(axis=1, keepdims=True)
    return np.einsum("eq,eq...->e...", w, v)


def write_history(path, history, extra=None):
    """Write one CSV row per converged step.

    Columns: step, load factor, Newton iterations of the converged attempt,
    final residual, cut-backs, attempts and iterations of all attempts
    (failed ones included), contact nodes whose status changed, wall time of
    all attempts, every reaction component, then ``extra`` (a list of dicts, one
    per step, e.g. gauges such as the current height).
    """
    rows = []
    for k, record in enumerate(history):
        row = {"step": record.step, "t": record.t, "iterations": record.iterations,
               "residual": record.residuals[-1], "cutbacks": record.cutbacks,
               "attempts": record.attempts, "all iterations": record.spent_iterations,
               "contact changes": record.contact_changes, "seconds": record.seconds}
        for name, value in record.reactions.items():
            value = np.atleast_1d(value)
            if value.size == 1:
                row[f"reaction {name}"] = float(value[0])
            else:
                for c, v in enumerate(value):
                    row[f"reaction {name} {'xyz'[c]}"] = float(v)
        if extra is not None:
            row.update(extra[k])
        rows.append(row)
    columns = list(dict.fromkeys(key for row in rows for key in row))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return path


class FieldWriter:
    """XDMF time series of a solid problem's fields (use as a context manager).

    Parameters
    ----------
    path : str or Path
        ``.xdmf`` file; meshio writes the ``.h5`` data beside it.
    problem : SolidProblem
    """

    def __init__(self, path, problem):
        self.path = Path(path).resolve()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.problem = problem
        mesh = problem.basis.mesh
        cell_type = MESHIO_CELLS.get(type(mesh).__name__)
        if cell_type is None:
            raise ValueError(f"no XDMF cell type for {type(mesh).__name__}")
        self._writer = meshio.xdmf.TimeSeriesWriter(str(self.path))
        points = np.zeros((mesh.nvertices, 3))
        points[:, : mesh.dim()] = mesh.p.T
        self._cells = [(cell_type, mesh.t.T)]
        self._points = points

    def __enter__(self):
        # meshio opens the .h5 file relative to the working directory: open
        # it from the output folder so that it lands beside the .xdmf file
        cwd = os.getcwd()
        os.chdir(self.path.parent)
        try:
            self._writer.__enter__()
        finally:
            os.chdir(cwd)
        self._writer.write_points_cells(self._points, self._cells)
        return self

    def __exit__(self, *exc):
        return self._writer.__exit__(*exc)

    def write(self, t, d, evaluation=None):
        """Write the fields at load factor ``t`` for coefficients ``d``."""
        problem = self.problem
        u = np.zeros((problem.basis.mesh.nvertices, 3))
        disp = nodal_displacements(problem.basis, d)
        u[:, : disp.shape[1]] = disp
        point_data = {"displacement": u}
        evaluation = evaluation or problem.evaluate(d, tangent=False)
        dx = problem.assembler.layout.dx
        sigma = problem.cauchy_stress(evaluation)
        s = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
        von_mises = np.sqrt(1.5 * np.einsum("nij,nij->n", s, s))
        cell_data = {
            "stress": [cell_averages(sigma.reshape(-1, 9), dx)],
            "von_mises": [cell_averages(von_mises, dx)],
            "plastic_strain": [cell_averages(problem.state.alpha, dx)],
        }
        self._writer.write_data(t, point_data=point_data, cell_data=cell_data)
