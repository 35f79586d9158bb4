"""Re-referencing: rebuild the RK functions on the current configuration.

The paper's RK functions are Lagrangian: built once on the initial
configuration, with their supports and the background cells that carry
the quadrature in material coordinates.  Under large deformation the map
from those to the current configuration degrades (the supports of the
particles near a fold are sheared flat, the cells distort, and ``det F``
at a point finally turns negative).  The updated Lagrangian RK of the
literature (an extension the paper leaves open) rebuilds the functions on
a later configuration and continues from there.

With ``discretization.rereference = θ`` (0 < θ < 1) a run rebuilds when,
after a converged step, the deformation since the last reference has
``det F < θ`` at a quadrature point or the Jacobian of a
background cell below ``θ`` times its value at the reference (the cell
distorted), and when a step fails after progress since the last
reference.  A rebuild that is refused (a cell of the current configuration
folded within one step, a moment matrix that cannot be inverted there)
ends the rebuilds: the run goes on on the last reference, whose quadrature
is still valid.  The rebuild (:meth:`Rereferencing.rebuild`):

- moves the mesh vertices (the particles) to their current positions,
  ``x = X + u``; the background cells are the current cells (refused if
  one is folded, which the threshold prevents);
- builds the scene's discretization on that mesh: new RK functions, VCI
  or smoothing cells, contact points, prescribed conditions (their values
  counted from the reference); support radii kept, or re-dilated with the
  current particle spacing (``discretization.rereference_supports =
  "spacing"``: ``a_I ← a_I h_I,now / h_I,ref`` with ``h_I`` the longest mesh
  edge at the particle, the direction a compressed body stretches in);
- carries the material state to the new quadrature points by the L²
  projection of :class:`~skfem_rkpm.approximation.transfer.PointTransfer`:
  the elastic left Cauchy-Green tensor ``b_e`` (which is the new state
  ``C_p⁻¹``, :mod:`skfem_rkpm.mechanics.referenced`), the equivalent plastic
  strain and the total deformation gradient ``F = F_incr · F_ref``; the
  contact states (per contact node, in current coordinates) are the same
  nodes' and are kept;
- restarts Newton from zero displacement on the new reference, with the
  load factor, step count and step control where they were.

Outputs stay in the original frame: the fields' displacements and the
gauges are counted from the initial configuration.
"""

import dataclasses

import numpy as np
from skfem.quadrature import get_quadrature

from ..approximation.transfer import PointTransfer, local_radius
from ..mechanics.problem import InvertedElementError
from ..mechanics.referenced import (ReferencedMaterial, elastic_left_cauchy_green,
                                    rebased_state, reference_volume_ratio,
                                    total_deformation_gradient)
from ..solvers.newton import Prescribed, Result
from .io import nodal_displacements
from .scene_values import SceneError

__all__ = ["cell_jacobians", "Rereferencing", "RereferenceError", "Rebuild", "rereferencing_of",
           "solve_segments"]


#: how the material state reaches the new points: an L² fit with local
#: supports, one with the new basis's supports, or copied point by point (the
#: same cells and Gauss points on the moved mesh)
TRANSFERS = ("local", "basis", "points")


class RereferenceError(RuntimeError):
    """The current configuration cannot be a reference (a folded cell)."""


class Rebuild(Exception):
    """Raised after a converged step whose map has degraded: the caller
    rebuilds (:meth:`Rereferencing.rebuild`) at coefficients ``d`` and
    continues."""

    def __init__(self, reason, d):
        super().__init__(reason)
        self.reason, self.d = reason, d


def rereferencing_of(sim, log=None):
    """The :class:`Rereferencing` a scene asks for, or None."""
    disc = sim.scene["discretization"]
    threshold = disc.get("rereference")
    if threshold is None:
        return None
    if sim.method != "rkpm":
        raise SceneError("discretization.rereference: only for method rkpm (FEM "
                         "elements are the cells that fold); remove it for --method fem")
    if sim.partition is not None:
        raise SceneError("discretization.rereference: not with a partitioned problem "
                         "(mpiexec with the solver petsc); run it on one process")
    return Rereferencing(sim, threshold, disc.get("rereference_supports") or "keep", log,
                         disc.get("rereference_transfer") or "local")


class Rereferencing:
    """The chain of reference configurations of one run (``sim`` is
    rebuilt in place).

    Parameters
    ----------
    sim : Simulation
    threshold : float
        θ in (0, 1): rebuild when ``det F`` of the increment since the
        reference at a point, or the Jacobian ratio of a cell at a Gauss point, is below it.
    supports : {"keep", "spacing"}
        Support radii at a rebuild: the same, or scaled with the current spacing.
    """

    def __init__(self, sim, threshold, supports="keep", log=None, transfer="local"):
        if not 0.0 < float(threshold) < 1.0:
            raise ValueError(f"the re-referencing threshold must lie in (0, 1), not "
                             f"{threshold}")
        if supports not in ("keep", "spacing"):
            raise ValueError(f"supports must be 'keep' or 'spacing', not {supports!r}")
        if transfer not in TRANSFERS:
            raise ValueError(f"transfer must be one of {TRANSFERS}, not {transfer!r}")
        self.sim, self.threshold, self.supports = sim, float(threshold), supports
        self.transfer = transfer
        self.log = log or (lambda line: None)
        self.origin_mesh = sim.mesh
        #: vertex displacements of the reference from the initial configuration
        self.offset = np.zeros((sim.mesh.nvertices, sim.mesh.dim()))
        self.F_ref = None  # total deformation gradient at the reference's points
        self.t_ref = 0.0
        #: (load factor, reason) of every rebuild
        self.events = []
        #: (load factor, error) of a rebuild refused: no more are tried
        self.refused = None
        self._intorder = sim.scene["discretization"]["quadrature"]
        sim.rereferenced = self

    # -- when ---------------------------------------------------------------
    def degradation(self, d, evaluation):
        """``(smallest ratio, where)``: the smaller of ``det F`` of the
        increment at the quadrature points and the Jacobian ratios of the
        background cells at their Gauss points since the reference
        (:func:`cell_jacobians`)."""
        J = np.linalg.det(evaluation.F)
        cells = cell_jacobians(self.sim.mesh, nodal_displacements(self.sim.basis, d),
                               self._intorder)
        point, cell = int(np.argmin(J)), np.unravel_index(np.argmin(cells), cells.shape)
        if J[point] <= cells[cell]:
            return float(J[point]), f"det F = {J[point]:.3g} at material point {point}"
        return (float(cells[cell]),
                f"cell {cell[0]} distorted (Jacobian {cells[cell]:.3g} of the reference's "
                f"at Gauss point {cell[1]})")

    def after_step(self, record, d, evaluation):
        """Raise :class:`Rebuild` when the map since the reference has degraded
        (not after a refused rebuild: the run goes on on the last reference)."""
        if self.refused is not None:
            return
        value, where = self.degradation(d, evaluation)
        if value < self.threshold:
            raise Rebuild(f"{where} < {self.threshold:g}", d)

    def can_retry(self, t):
        """A failed step at converged load factor ``t``: rebuild and retry
        when the run has gone on since the last reference."""
        return self.refused is None and t > self.t_ref + 1e-12

    # -- how ----------------------------------------------------------------
    def rebuild(self, d, t, reason, stepper=None):
        """Rebuild ``sim`` on the configuration of coefficients ``d`` (a
        converged state at load factor ``t``, the problem's committed state);
        returns the coefficients on the new reference (zero).  ``stepper``:
        the Newton stepper state, whose rate predictor is reset."""
        from .build import build

        sim = self.sim
        old_basis, old_problem, mesh = sim.basis, sim.problem, sim.mesh
        u_vertices = nodal_displacements(old_basis, d)
        cells = cell_jacobians(mesh, u_vertices, self._intorder)
        if not (cells > 0).all():
            cell = int(np.argmin(cells.min(axis=1)))
            raise RereferenceError(f"the current configuration has folded cells (cell "
                                   f"{cell}: Jacobian ratio {cells.min():.3g} at a Gauss "
                                   f"point): it cannot be a reference; use a larger "
                                   f"discretization.rereference threshold")
        new_mesh = dataclasses.replace(mesh, doflocs=mesh.p + u_vertices.T)
        radius = np.asarray(old_basis.radius, float)
        if self.supports == "spacing":
            # the longest edge at each particle: a support must reach its
            # neighbours along the stretched direction of a compressed body
            radius = radius * local_radius(new_mesh) / local_radius(mesh)
        # the old material points, where they are now, and what they carry
        dim = mesh.dim()
        X = np.asarray(old_basis.global_coordinates()).reshape(dim, -1)
        x_old = X + np.asarray(old_basis.interpolate(d)).reshape(dim, -1)
        F_incr = old_problem.evaluate(d, tangent=False).F
        volume = old_problem.assembler.layout.dx.ravel() * np.linalg.det(F_incr)
        b_e = elastic_left_cauchy_green(old_problem.material_gradient(F_incr),
                                        old_problem.state)
        F_total = total_deformation_gradient(F_incr, self.F_ref)
        new = build(sim.scene, sim.method, mesh=new_mesh, radius=radius)
        nodal = getattr(new.basis, "nodal_quadrature", None) is not None
        same = nodal or self.transfer == "points"
        transfer = PointTransfer(new.basis, x_old, volume, same_points=same,
                                 radius=(local_radius(new_mesh) if self.transfer == "local"
                                         else None))
        state = rebased_state(transfer(b_e), np.maximum(transfer(old_problem.state.alpha),
                                                        0.0))
        problem = new.problem
        problem.material = ReferencedMaterial(old_problem.material,
                                              reference_volume_ratio(state))
        problem.state = state
        if problem.stabilization is not None:
            problem.stabilization = problem._stabilization()
        self.F_ref = transfer(F_total)
        for old, now in zip(sim.tools, new.tools):
            _keep_contact(old, now)
        prescribed = [_counted_from(p, t) for p in new.prescribed]
        points = {name: self._position(old_basis, d, X_now)
                  for name, X_now in sim.points.items()}
        self.offset = self.offset + u_vertices
        for name in ("mesh", "basis", "problem", "load", "tools", "follower_loads"):
            setattr(sim, name, getattr(new, name))
        sim.prescribed, sim.points = prescribed, points
        self.t_ref = t
        self.events.append((t, reason))
        if stepper is not None:
            stepper.rate = None
        self.log(f"re-referenced at t = {t:.6g} ({reason}): {new.basis.N} dofs on the "
                 f"current configuration")
        return np.zeros(new.basis.N)

    @staticmethod
    def _position(basis, d, X):
        """Current position of a point at ``X`` of the reference."""
        X = np.asarray(X, float)
        return X + (basis.probes(X[:, None]) @ d).ravel()

    def describe(self):
        """One line on the rebuilds, for the run's status."""
        text = "not re-referenced"
        if self.events:
            where = ", ".join(f"{t:.4g}" for t, _ in self.events)
            text = f"re-referenced {len(self.events)} times (at t = {where})"
        if self.refused is not None:
            t, err = self.refused
            text += (f"; a rebuild at t = {t:.4g} was refused ({err}), the run went on "
                     f"on the last reference")
        return text


def _keep_contact(old, now):
    """The contact state and penalties of ``old`` on ``now`` (the same nodes
    on the new reference): the penalties of the initial spacing, since a
    penalty of the current spacing would change the pressure of the
    penetrations reached."""
    now.set_state(old.get_state())
    inner_old, inner_now = getattr(old, "contact", old), getattr(now, "contact", now)
    for name in ("omega_n", "omega_t"):
        if hasattr(inner_old, name):
            setattr(inner_now, name, getattr(inner_old, name))


def cell_jacobians(mesh, u, intorder):
    """Jacobians of the cells' isoparametric maps through the vertices moved
    by ``u`` (nvertices, dim) over those of the unmoved cells, at the Gauss
    points of degree ``intorder`` (ncells, nqp): where the quadrature of a
    background cell sits.  Unlike the corner Jacobians, they stay positive
    when a free side folds flat onto a tool (the corner angle at 180°) while
    the cell still covers its area."""
    X, _ = get_quadrature(mesh.refdom, intorder)
    moved = dataclasses.replace(mesh, doflocs=mesh.p + np.asarray(u).T)
    return moved._mapping().detDF(X) / mesh._mapping().detDF(X)


def _counted_from(prescribed, t_ref):
    """``prescribed`` with its values counted from load factor ``t_ref``
    (displacements on the new reference are increments)."""
    values = prescribed.values
    if callable(values):
        def increment(t, x, values=values):
            return np.asarray(values(t, x), float) - np.asarray(values(t_ref, x), float)
    else:
        if float(values) == 0.0:
            return prescribed
        value = float(values)

        def increment(t, x):
            return np.full(x.shape[1], (t - t_ref) * value)
    return Prescribed(prescribed.boundary, prescribed.component, increment,
                      prescribed.method)


#: why a rebuild may be refused: a folded cell, a moment matrix or transfer
#: that cannot be formed on the current configuration
REFUSALS = (RereferenceError, InvertedElementError, ValueError)


def solve_segments(rereferencing, solve, stepper):
    """Run ``solve(d0)`` (Newton from coefficients ``d0``, None at the
    start, with the current ``sim`` and ``stepper``), rebuilding on
    :class:`Rebuild` and after a failed step that followed progress since
    the last reference; returns the last result."""
    d0 = None
    while True:
        try:
            result = solve(d0)
        except Rebuild as signal:
            try:
                d0 = rereferencing.rebuild(signal.d, stepper.t, signal.reason, stepper)
            except REFUSALS as err:
                # the step converged on the last reference, whose quadrature is
                # valid: go on there, as the Lagrangian functions do
                rereferencing.refused = (stepper.t, err)
                d0 = signal.d
            continue
        if result.completed or not rereferencing.can_retry(stepper.t):
            return result
        try:
            d0 = rereferencing.rebuild(result.d, stepper.t,
                                       f"a step failed: {result.error}", stepper)
        except REFUSALS as err:
            result.message += f"; re-referencing refused: {err}"
            return result
