"""Results on disk: step history as CSV (and JSON lines), fields as an XDMF
time series.

Everything is written so that a run killed at any moment keeps every step
it finished: ``history.csv`` and ``history.jsonl`` grow by one appended row
per step; the fields of a step go to their own HDF5 file
(``fields/step-000012.h5``, written under a temporary name and renamed)
and the index ``fields.xdmf`` is replaced atomically after each of them.
The index opens in ParaView: nodal displacements as point data (use *Warp
By Vector*), cell averages of the quadrature-point state (Cauchy stress,
equivalent plastic strain) as cell data (with nodal integration the state
of every particle as point data).  For RK bases the nodal
displacements are the nodal values ``Λᵀ d`` (Eq. 3.32), not the
coefficients.
"""

import csv
import io
import json
import re
from pathlib import Path

import numpy as np

from ..solvers.newton import StepRecord
from .folder import FolderError, atomic_path, open_append, write_atomic

__all__ = ["nodal_displacements", "corner_jacobians", "xdmf_cells", "cell_averages",
           "nodal_plastic_strain",
           "history_row", "write_history",
           "HistoryFile", "record_to_json", "record_from_json", "FieldWriter"]

#: XDMF topology of each scikit-fem mesh type
XDMF_CELLS = {"MeshTri1": "Triangle", "MeshQuad1": "Quadrilateral",
              "MeshTet1": "Tetrahedron", "MeshHex1": "Hexahedron"}


def xdmf_cells(mesh):
    """The cells of ``mesh`` (ncells, vertices) in XDMF's (VTK's) vertex
    order: scikit-fem numbers the vertices of a hexahedron otherwise."""
    if type(mesh).__name__ == "MeshHex1":
        from skfem.io.meshio import HEX_MAPPING  # meshio: 0.15 s to import

        return mesh.t[HEX_MAPPING[:8]].T
    return mesh.t.T


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


def corner_jacobians(mesh, u):
    """``det F`` at the corners of every cell of the mesh moved by the vertex
    displacements ``u`` (nvertices, dim), shape (ncells, ncorners).

    At each corner, the determinant of the edges to its neighbours along
    the reference axes (quadrilaterals, hexahedra) or to the other vertices
    (triangles, tetrahedra), deformed over undeformed: ``det F`` of the
    bilinear or trilinear (linear) map through the moved vertices, at the
    vertex.  For Q1, P1, Hex1 and Tet1 elements this is the
    discretization's own ``det F`` there; for RK particles and quadratic
    elements that of the cells drawn in the figures.  Negative: the cell is
    folded at that corner.
    """
    t = mesh.t[:mesh.refdom.nnodes]
    X = mesh.p
    x = X + np.asarray(u).T
    edges = _corner_edges(mesh)  # (ncorners, dim): the corners each edge ends at

    def volumes(points):
        corners = points[:, t]  # (dim, ncorners, ncells)
        vectors = corners[:, edges] - corners[:, :, None]  # (dim, ncorners, dim, ncells)
        return np.linalg.det(np.moveaxis(vectors, (0, 2), (-2, -1)))  # (ncorners, ncells)

    return (volumes(x) / volumes(X)).T


def _corner_edges(mesh):
    """For each corner of the reference cell, the corners at the ends of its
    ``dim`` edges: the neighbours along each reference axis (tensor-product
    cells) or the other vertices in order (simplices)."""
    dim = mesh.dim()
    corners = np.asarray(type(mesh).elem().doflocs)[:mesh.refdom.nnodes]
    n = len(corners)
    if n == dim + 1:  # a simplex
        return np.array([[j for j in range(n) if j != i] for i in range(n)])
    edges = np.empty((n, dim), dtype=int)
    for i, c in enumerate(corners):
        for axis in range(dim):
            other = c.copy()
            other[axis] = 1.0 - other[axis]
            edges[i, axis] = np.flatnonzero(np.all(corners == other, axis=1))[0]
    return edges


def material_fields(problem, evaluation):
    """``dx`` (nelems, nqp), the Cauchy stress (n, 3, 3) and the equivalent
    plastic strain (n,) at the material points of the whole domain: a
    partitioned problem (``gather_points``) gathers them from every rank on
    rank 0 (the others get None), and must be called on every rank."""
    sigma = problem.gather_points(problem.cauchy_stress(evaluation))
    alpha = problem.gather_points(problem.state.alpha)
    if problem.whole_dx is None:  # a partitioned problem, not rank 0
        return None
    return problem.whole_dx, sigma, alpha


def cell_averages(values, dx):
    """Volume averages per cell of point values (n, ...) on a (nelems, nqp) rule."""
    nelems, nqp = dx.shape
    v = np.asarray(values).reshape((nelems, nqp) + np.shape(values)[1:])
    w = dx / dx.sum(axis=1, keepdims=True)
    return np.einsum("eq,eq...->e...", w, v)


def nodal_plastic_strain(problem):
    """Equivalent plastic strain averaged from the cells to the mesh vertices
    (with nodal integration: the values at the particles; a partitioned
    problem: its last gathered state, on rank 0)."""
    mesh = problem.basis.mesh
    if getattr(problem.basis, "nodal_quadrature", None) is not None:
        return problem.state.alpha
    if problem.whole_state is None:  # partitioned
        raise ValueError("the plastic strain of a partitioned problem is known on "
                         "rank 0 only, after gathered_state() (a run with an output "
                         "folder)")
    cells = cell_averages(problem.whole_state.alpha, problem.whole_dx)
    total = np.bincount(mesh.t.ravel(), np.tile(cells, mesh.t.shape[0]),
                        minlength=mesh.nvertices)
    count = np.bincount(mesh.t.ravel(), minlength=mesh.nvertices)
    return total / np.maximum(count, 1)


def history_row(record, extra=None):
    """One CSV row of a step: step, load factor, Newton iterations of the
    converged attempt, final residual, cut-backs, attempts and iterations of
    all attempts (failed ones included), contact nodes whose status changed,
    wall time of all attempts, every reaction component, then ``extra`` (a
    dict, e.g. gauges such as the current height)."""
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
    row.update(extra or {})
    return row


def _csv_text(rows, columns, header=True):
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    if header:
        writer.writeheader()
    writer.writerows(rows)
    return text.getvalue()


def write_history(path, history, extra=None):
    """Write one CSV row per converged step (see :func:`history_row`);
    ``extra`` is a list of dicts, one per step.  The file is replaced
    atomically."""
    rows = [history_row(r, None if extra is None else extra[k])
            for k, r in enumerate(history)]
    columns = list(dict.fromkeys(key for row in rows for key in row))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomic(path, _csv_text(rows, columns))


class HistoryFile:
    """``history.csv`` grown by one appended row per step (O(1) a step).

    The columns are those of the first row; a row with a new column (it
    does not happen in a scene run: the reactions and gauges are fixed)
    rewrites the file atomically with the new header.  ``resume=True``
    continues an existing file.
    """

    def __init__(self, path, resume=False):
        self.path = Path(path)
        self.columns, self.rows = None, []
        if resume and self.path.exists():
            with open(self.path, newline="", encoding="utf-8") as handle:
                reader = csv.DictReader(handle)
                self.rows = list(reader)
                self.columns = reader.fieldnames

    def append(self, record, extra=None):
        row = history_row(record, extra)
        self.rows.append(row)
        if self.columns is None or not set(row) <= set(self.columns):
            self.columns = list(dict.fromkeys([*(self.columns or []), *row]))
            write_atomic(self.path, _csv_text(self.rows, self.columns))
            return
        with open_append(self.path, newline="", encoding="utf-8") as handle:
            handle.write(_csv_text([row], self.columns, header=False))


def record_to_json(record, gauges):
    """One line of ``history.jsonl``: a step's whole record and its gauges."""
    data = dict(vars(record))
    data["reactions"] = {k: np.asarray(v).tolist() for k, v in record.reactions.items()}
    return json.dumps({"record": data, "gauges": gauges}) + "\n"


def record_from_json(line):
    """``(StepRecord, gauges)`` of a line written by :func:`record_to_json`."""
    data = json.loads(line)
    record = dict(data["record"])
    record["reactions"] = {k: (np.array(v) if isinstance(v, list) else v)
                           for k, v in record["reactions"].items()}
    return StepRecord(**record), data["gauges"]


_XDMF_HEAD = """<?xml version="1.0"?>
<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2003/XInclude">
  <Domain>
    <Grid Name="mesh" GridType="Uniform">
      <Topology TopologyType="{topology}" NumberOfElements="{ncells}">
        <DataItem DataType="Int" Dimensions="{ncells} {nper}" Format="HDF" Precision="8">{folder}/mesh.h5:/cells</DataItem>
      </Topology>
      <Geometry GeometryType="XYZ">
        <DataItem DataType="Float" Dimensions="{npoints} 3" Format="HDF" Precision="8">{folder}/mesh.h5:/points</DataItem>
      </Geometry>
    </Grid>
    <Grid Name="fields" GridType="Collection" CollectionType="Temporal">
"""
_XDMF_STEP = """      <Grid Name="step {step}" GridType="Uniform">
        <xi:include xpointer="xpointer(//Grid[@Name=&quot;mesh&quot;]/*[self::Topology or self::Geometry])"/>
        <Time Value="{t!r}"/>
{attributes}      </Grid>
"""
_XDMF_ATTRIBUTE = """        <Attribute Name="{name}" AttributeType="{kind}" Center="{center}">
          <DataItem DataType="Float" Dimensions="{dims}" Format="HDF" Precision="8">{file}:/{name}</DataItem>
        </Attribute>
"""
_XDMF_TAIL = """    </Grid>
  </Domain>
</Xdmf>
"""
_ATTRIBUTE_KINDS = {1: "Scalar", 3: "Vector", 9: "Tensor"}


class FieldWriter:
    """XDMF time series of a solid problem's fields, one HDF5 file per step.

    ``fields.xdmf`` indexes ``fields/mesh.h5`` (vertices and cells) and one
    ``fields/step-NNNNNN.h5`` per written step; each step file is complete
    before it is renamed into place, and the index is replaced atomically
    after it, so a kill at any moment leaves a readable series of every
    step written.

    Parameters
    ----------
    path : str or Path
        The ``.xdmf`` index; the HDF5 files go to the folder of the same
        name without the suffix.
    problem : SolidProblem
    keep_until : int, optional
        Continue an existing series (to resume a run): keep its steps up to
        this step number, delete later ones (written after the checkpoint
        the run resumes from).  By default a new series is started.
    owner : RunFolder, optional
        The run folder: every file is entered in its manifest before it is
        written (:meth:`~skfem_rkpm.runs.folder.RunFolder.claim`), and only
        files it lists are deleted.

    It is also a context manager (nothing to close: every write is complete).
    """

    def __init__(self, path, problem, keep_until=None, owner=None):
        self.path = Path(path)
        self.folder = self.path.with_suffix("")
        self.owner = owner
        if self.folder.is_symlink():
            raise FolderError(f"{self.folder} is a symbolic link: a run writes only its "
                              f"own files; remove the link")
        if not self.folder.exists():
            self._claim(self.folder, folder=True)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.problem = problem
        #: vertex displacements added to the problem's (a run re-referenced
        #: on a later configuration writes those from the initial one)
        self.offset = None
        # nodal integration: the material points are the particles (vertices),
        # whose state is written as it is, at the vertices
        self._nodal = getattr(problem.basis, "nodal_quadrature", None) is not None
        mesh = problem.basis.mesh
        self.topology = XDMF_CELLS.get(type(mesh).__name__)
        if self.topology is None:
            raise ValueError(f"no XDMF cell type for {type(mesh).__name__}")
        self.entries = []  # (step, t, file name, attribute shapes)
        if keep_until is not None:
            self._keep(keep_until)
        if keep_until is None or not (self.folder / "mesh.h5").exists():
            points = np.zeros((mesh.nvertices, 3))
            points[:, : mesh.dim()] = mesh.p.T
            self._claim(self.folder / "mesh.h5")
            import h5py  # imported when fields are written: 30 ms

            with atomic_path(self.folder / "mesh.h5") as tmp, h5py.File(tmp, "x") as f:
                f["points"] = points
                f["cells"] = xdmf_cells(mesh).astype(np.int64)
        self._write_index()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None

    def _claim(self, path, folder=False):
        if self.owner is not None:
            self.owner.claim(path, folder=folder)

    def _keep(self, last):
        import h5py

        for file in sorted(self.folder.glob("step-*.h5")):
            match = re.fullmatch(r"step-(\d+)\.h5", file.name)
            if match is None or (self.owner is not None and not self.owner.owns(file)):
                continue
            step = int(match.group(1))
            if step > last:
                file.unlink()
                continue
            with h5py.File(file, "r") as f:
                shapes = {name: f[name].shape for name in f}
                self.entries.append((step, float(f.attrs["t"]), file.name, shapes))

    def _write_index(self):
        mesh = self.problem.basis.mesh
        parts = [_XDMF_HEAD.format(topology=self.topology, ncells=mesh.t.shape[1],
                                   nper=mesh.t.shape[0], npoints=mesh.nvertices,
                                   folder=self.folder.name)]
        for step, t, name, shapes in self.entries:
            attributes = "".join(
                _XDMF_ATTRIBUTE.format(
                    name=key, kind=_ATTRIBUTE_KINDS[int(np.prod(shape[1:]))],
                    center="Node" if key == "displacement" or self._nodal else "Cell",
                    dims=" ".join(map(str, shape)), file=f"{self.folder.name}/{name}")
                for key, shape in shapes.items())
            parts.append(_XDMF_STEP.format(step=step, t=float(t), attributes=attributes))
        parts.append(_XDMF_TAIL)
        self._claim(self.path)
        write_atomic(self.path, "".join(parts))

    def write(self, t, d, evaluation=None, step=None, fields=None):
        """Write the fields at load factor ``t`` for coefficients ``d``
        (``step``: the step number, by default one more than the last;
        ``fields``: :func:`material_fields` of ``evaluation``, if already
        gathered)."""
        step = (self.entries[-1][0] + 1 if self.entries else 1) if step is None else step
        problem = self.problem
        u = np.zeros((problem.basis.mesh.nvertices, 3))
        disp = nodal_displacements(problem.basis, d)
        u[:, : disp.shape[1]] = disp if self.offset is None else disp + self.offset
        if fields is None:
            if problem.partitioned:
                raise ValueError("the fields of a partitioned problem are gathered from "
                                 "every rank: call material_fields(problem, evaluation) "
                                 "on every rank and pass its result as fields=")
            fields = material_fields(problem, evaluation or problem.evaluate(d, tangent=False))
        dx, sigma, alpha = fields
        s = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
        von_mises = np.sqrt(1.5 * np.einsum("nij,nij->n", s, s))
        fields = {"stress": sigma.reshape(-1, 9), "von_mises": von_mises,
                  "plastic_strain": alpha}
        if not self._nodal:
            fields = {key: cell_averages(value, dx) for key, value in fields.items()}
        data = {"displacement": u, **fields}
        name = f"step-{step:06d}.h5"
        self._claim(self.folder / name)
        import h5py

        with atomic_path(self.folder / name) as tmp, h5py.File(tmp, "x") as f:
            f.attrs["t"] = float(t)
            for key, value in data.items():
                f[key] = value
        self.entries = [e for e in self.entries if e[0] < step]
        self.entries.append((step, float(t), name, {k: v.shape for k, v in data.items()}))
        self._write_index()
