"""Frictional contact of a 3D body with a moving rigid tool surface: the
penalty (Eq. 4.5-4.6) or augmented Lagrangian Coulomb law of
:mod:`.friction` with the slip direction a vector of the tangent plane,
its force and consistent tangent (the 3D form of Eq. 4.27-4.29), at the
slave points of :mod:`.slave_points` against a tool of :mod:`.surfaces`.

The contact node ``K`` sees the gap and slip of its slave points
(the particle itself for nodal collocation, hat-weighted averages of the
boundary Gauss points otherwise):

    ĝ_K = W_K⁻¹ Σ_q M_Kq g_q,           ŝ_K = W_K⁻¹ Σ_q M_Kq P_q Δξ_q,

with ``P = I - n nᵀ`` the projection on the tangent plane of the master
surface and ``Δξ`` the slip of the point relative to the tool since the
last converged step (Eq. 4.11; the change of its position in the tool's
frame, so that rotating rolls are handled like translating platens).
Its tractions are ``t_n = ⟨λ_n - ω_n ĝ⟩`` and the return map of the
trial ``T* = λ_t - ω_t φ ŝ`` (``φ`` the part of the step spent in
contact); the points carry ``t_q = Σ_K N_qK (t_n,K n_q + T_K)``.
"""

import numpy as np

from .friction import ContactState, coulomb_vector
from .rigid_contact import (RigidContact, ToolSideError, _check_finite_traction,
                            _touch_fraction)

__all__ = ["SurfaceContact", "symmetry_projection"]


def _outer(a, b):
    return np.einsum("ni,nj->nij", a, b)


def _slip_derivative(normal, curvature, slipped):
    """``D = ∂(P Δξ)/∂x = P - (n·Δξ) C - n (C Δξ)ᵀ`` per point, with
    ``∂Δξ/∂x = I`` and ``∂n/∂x = C`` (the curvature of the master surface)."""
    n, dim = normal.shape
    P = np.eye(dim)[None] - _outer(normal, normal)
    along = np.einsum("ni,ni->n", normal, slipped)
    return (P - along[:, None, None] * curvature
            - _outer(normal, np.einsum("nij,nj->ni", curvature, slipped)))


def symmetry_projection(mesh, nodes, symmetry, dim=3):
    """``Q_K`` (m, dim, dim): the projection off the normals of the
    symmetry planes through each contact node (the identity elsewhere).

    ``nodes`` (m,) are the mesh vertices of the contact nodes,
    ``symmetry`` pairs ``(boundary, normal)``: a name in ``mesh.boundaries``
    (or facet indices) and the plane's normal.  Planes that meet at a node
    at an angle (a wedge's sides) are projected off together,
    ``Q = I - E (EᵀE)⁻¹ Eᵀ`` with their normals ``E``."""
    m = len(nodes)
    on = np.zeros((m, 0), bool)
    normals = []
    for boundary, normal in symmetry:
        n = np.asarray(normal, float).ravel()
        if n.shape != (dim,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
            raise ValueError(f"the normal of symmetry plane {boundary!r} must be "
                             f"{dim} finite numbers, not all zero; got {normal!r}")
        if isinstance(boundary, str):
            if boundary not in (mesh.boundaries or {}):
                raise ValueError(f"symmetry plane {boundary!r}: the mesh has no such "
                                 f"boundary; it has {sorted(mesh.boundaries or {})}")
            facets = mesh.boundaries[boundary]
        else:
            facets = np.asarray(boundary, dtype=np.int64)
        vertices = np.unique(mesh.facets[:, facets])
        on = np.column_stack([on, np.isin(nodes, vertices)])
        normals.append(n / np.linalg.norm(n))
    Q = np.broadcast_to(np.eye(dim), (m, dim, dim)).copy()
    if not normals:
        return Q
    E_all = np.array(normals).T  # (dim, planes)
    keys = on @ (1 << np.arange(on.shape[1]))
    for key in np.unique(keys[keys > 0]):
        E = E_all[:, [(key >> k) & 1 == 1 for k in range(on.shape[1])]]
        # least-squares projection: a rank-deficient E (parallel planes) is fine
        Q[keys == key] = np.eye(dim) - E @ np.linalg.pinv(E)
    return Q


def _stick_slip_operator(trial, shear, pressure, slip, active, mu):
    """``S = ∂T/∂T*`` per node: ``I`` in stick, ``μ t_n / |T*| (I - τ τᵀ)``
    in slip (``τ = T*/|T*|``), 0 apart or without friction."""
    m, dim = trial.shape
    S = np.zeros((m, dim, dim))
    if mu == 0.0:
        return S, np.zeros((m, dim))
    stick = active & ~slip
    S[stick] = np.eye(dim)
    size = np.linalg.norm(trial, axis=1)
    tau = np.where(slip[:, None], trial / np.where(slip, size, 1.0)[:, None], 0.0)
    if np.isfinite(mu):
        S[slip] = ((mu * pressure[slip] / size[slip])[:, None, None]
                   * (np.eye(dim)[None] - _outer(tau[slip], tau[slip])))
    return S, tau


def _surface_tangent(coupling, proj, pts, law, slipped, omega_n, omega_t, mu, Q=None):
    """Consistent tangent ``K = Gᵀ X G`` of the contact force
    ``f = -Gᵀ (w t)`` (the 3D form of Eq. 4.28-4.29), with the blocks

        X_pq = Σ_K M_Kp M_Kq [α_K n_p n_qᵀ + A_K D_q + b_K n_qᵀ]
               - δ_pq w_p t̄_n,p C_p

    between slave points ``p, q`` (``M = Nᵀ diag(w)``): ``α_K = ω_n/W_K``
    on pressed nodes (Eq. 4.5), ``A_K = ω_t φ_K S_K / W_K`` and
    ``b_K = (ω_t φ'_K S_K ŝ_K + μ ω_n τ_K [slip]) / W_K`` from the return
    map (Eq. 4.6, ``S = ∂T/∂T*``), ``D_q`` the derivative of the projected
    slip (:func:`_slip_derivative`) and ``C_p = ∂n/∂x`` at the point; a
    node on symmetry planes has ``S_K Q_K`` in ``A_K`` (its slip is
    ``Q_K ŝ_K``, :func:`symmetry_projection`).
    """
    pressure, shear, slip, active, trial, mean_slip, phi, dphi = law
    normal = proj.normal.T
    dim = normal.shape[1]
    inv_W = 1.0 / pts.node_weights
    p, q = coupling.rows, coupling.cols
    blocks = ((omega_n * coupling.scalar(active * inv_W))[:, None, None]
              * _outer(normal[p], normal[q]))
    if mu > 0:
        S, tau = _stick_slip_operator(trial, shear, pressure, slip, active, mu)
        A = (omega_t * phi * inv_W)[:, None, None] * (S if Q is None else S @ Q)
        b = (omega_t * dphi * inv_W)[:, None] * np.einsum("kij,kj->ki", S, mean_slip)
        if np.isfinite(mu):
            b += (mu * omega_n * (slip & active) * inv_W)[:, None] * tau
        A_pq = np.stack([coupling.scalar(A[:, i, j]) for i in range(dim)
                         for j in range(dim)], axis=-1).reshape(-1, dim, dim)
        b_pq = np.stack([coupling.scalar(b[:, i]) for i in range(dim)], axis=-1)
        D = _slip_derivative(normal, proj.curvature, slipped)
        blocks += np.einsum("kij,kjl->kil", A_pq, D[q]) + _outer(b_pq, normal[q])
    blocks[coupling.diagonal] -= ((pts.weights * (pts.hats @ pressure))[:, None, None]
                                  * proj.curvature)
    return coupling.tangent(blocks)


def _check_initial_side_3d(tool, X, spacing):
    """:class:`ToolSideError` if every slave point starts behind the tool
    surface, somewhere deeper than the particle ``spacing``."""
    gap = tool.project(X, 0.0).gap
    if gap.max() > 1e-9 * spacing or gap.min() >= -spacing:
        return
    raise ToolSideError("orientation", "faces away from the part (the normal of a "
                        "plane, the side of a cylinder, sphere or torus, or the "
                        "winding of a triangulated surface must put the part on the "
                        "positive side); flip it",
                        f"at t = 0 all {gap.size} slave points are behind its surface, "
                        f"up to {-gap.min():.4g} deep, {-gap.min() / spacing:.3g} "
                        "particle spacings", tool.name)


class SurfaceContact(RigidContact):
    """Penalty or augmented-Lagrangian frictional contact of a 3D body with
    a rigid tool surface (Sec. 4.3, Eq. 4.25-4.29 with vector slip), a
    contribution for :func:`skfem_rkpm.solvers.newton.newton_steps`.

    The same parameters and methods as :class:`RigidContact`, with
    ``tool`` a surface of :mod:`skfem_rkpm.mechanics.surfaces` (anything
    with ``project(x, t)`` returning point, normal, gap and the curvature
    tensor ``∂n/∂x``, ``to_body(x, t)`` and ``placement(t)``) and
    ``problem.model == "3d"``.  Tangential tractions are vectors (``shear``
    of the state has shape ``(m, 3)``).

    ``symmetry``: pairs ``(boundary, normal)`` of the model's symmetry
    planes; contact nodes on them carry no tangential traction along the
    plane's normal (:func:`symmetry_projection`).
    """

    _PRODUCT_MAP = True  # one sparse matrix-vector product instead of two products

    def __init__(self, problem, tool, *args, symmetry=(), **kwargs):
        self._symmetry = None
        self._held_stick = None  # nodes held in stick by sticking() (a linear model)
        self._linear = None  # (d, t, proj, slipped, law, f, K) of the last evaluation
        super().__init__(problem, tool, *args, **kwargs)
        symmetry = list(symmetry or ())
        if symmetry:
            if self.points.nodes is None:
                raise ValueError("symmetry planes need contact nodes at mesh vertices: "
                                 "collocation 'nodal' or 'quadrature', not 'gauss'")
            self._symmetry = symmetry_projection(problem.basis.mesh, self.points.nodes,
                                                 symmetry, self.points.dim)
            self.restart()

    def _check_tool(self, tool, problem):
        """TypeError unless ``tool`` is a 3D surface; ValueError unless the
        model is 3D."""
        if not all(hasattr(tool, a) for a in ("project", "to_body", "placement")):
            raise TypeError("tool must be a 3D surface (Plane, Cylinder, Sphere, Torus, "
                            f"TriangulatedSurface), not {tool!r}")
        if problem.model != "3d":
            raise ValueError(f"SurfaceContact needs a 3D model, not {problem.model!r}; "
                             "use RigidContact with a 2D tool")

    def _check_start(self):
        """:class:`ToolSideError` if the surface starts facing away."""
        _check_initial_side_3d(self.tool, self.points.X, self.points.spacing)

    def _initial_state(self):
        X, m, dim = self.points.X, self.points.m, self.points.dim
        proj = self.tool.project(X, 0.0)
        return ContactState(X.copy(), proj.gap, proj.normal, np.zeros_like(X),
                            self.tool.to_body(X, 0.0), self.points.average(proj.gap),
                            np.zeros(m), np.zeros((m, dim)), np.zeros(m, bool),
                            np.zeros(m, bool), np.zeros(dim))

    def _slip(self, relative, t):
        """Slip ``Δξ`` (n, d) of the points relative to the tool since the
        last converged step, in the world frame at load factor ``t``."""
        R, _ = self.tool.placement(t)
        return (R @ (relative - self.state.relative)).T

    def _mean_slip(self, normal, slipped):
        """``ŝ_K``: hat-weighted averages of the tangential slip ``P Δξ``."""
        along = np.einsum("ni,ni->n", normal, slipped)
        tangential = slipped - along[:, None] * normal
        mean = np.stack([self.points.average(c) for c in tangential.T], axis=1)
        return self._project(mean)

    def _project(self, vectors):
        """Nodal vectors (m, d) without their parts along the normals of the
        symmetry planes through the nodes."""
        if self._symmetry is None:
            return vectors
        return np.einsum("kij,kj->ki", self._symmetry, vectors)

    def restart(self, t=None):
        """As :meth:`RigidContact.restart`; the tangential multipliers of
        nodes on symmetry planes lie in the planes."""
        super().restart(t)
        if getattr(self, "_symmetry", None) is not None:
            self.multipliers = (self.multipliers[0], self._project(self.multipliers[1]))

    def _law(self, proj, slipped):
        """Nodal tractions: ``t_n = ⟨λ_n - ω_n ĝ⟩`` (Eq. 4.5) and the return
        map (Eq. 4.6) of ``T* = λ_t - ω_t φ ŝ`` (Eq. 4.11 for the slip)."""
        pts, state = self.points, self.state
        node_gap = pts.average(proj.gap)
        pressed = node_gap - self.multipliers[0] / self.omega_n
        active, pressure = self._normal_law(pressed)
        mean_slip = self._mean_slip(proj.normal.T, slipped)
        phi, dphi = _touch_fraction(node_gap, state.node_gap, state.active)
        trial = self.multipliers[1] - (self.omega_t * phi)[:, None] * mean_slip
        shear, slip = self._freeze.release(*coulomb_vector(pressure, trial, self.mu))
        if self._held_stick is not None:  # the stick branch of sticking()'s nodes
            shear = np.where(self._held_stick[:, None], trial, shear)
            slip = slip & ~self._held_stick
        law = (pressure, np.where(active[:, None], shear, 0.0), slip & active, active,
               trial, mean_slip, phi, dphi)
        return node_gap, law

    def evaluate(self, d, t, tangent=True):
        """Contact force (added to the internal force) and its tangent at
        coefficients ``d`` and load factor ``t``; ``tangent=False`` skips the
        tangent (None), for explicit time steps that need the force only."""
        pts = self.points
        x = pts.X + pts.displacements(d)
        proj = self.tool.project(x, t)
        relative = self.tool.to_body(x, t)
        slipped = self._slip(relative, t)
        node_gap, law = self._law(proj, slipped)
        pressure, shear = law[0], law[1]
        tangential = (pts.hats @ shear).T
        traction = (pts.hats @ pressure) * proj.normal + tangential
        _check_finite_traction(traction, pts.X, self.name)
        f = self._coupling.GT @ (-(pts.weights * traction)).T.ravel()
        K = _surface_tangent(self._coupling, proj, pts, law, slipped, self.omega_n,
                             self.omega_t, self.mu, self._symmetry) if tangent else None
        self._normals = proj.normal
        self._sticking_slip = law[6][:, None] * law[5]  # φ ŝ: what stick must keep at 0
        size = np.linalg.norm(tangential, axis=0)
        direction = tangential / np.where(size > 0, size, 1.0)
        self.trial = ContactState(x, proj.gap, proj.normal, direction, relative, node_gap,
                                  pressure, shear, law[2], law[3],
                                  (pts.weights * traction).sum(axis=1), t)
        self._linear = (d, t, proj, slipped, law, f, K)
        return f, K

    def linearized_law(self, delta):
        """The trial traction ``T*`` (m, d) and the pressure ``λ_n - ω_n ĝ``
        (m,) of the nodes at ``d + δ`` in the linear model of the last
        evaluation at ``d``: ``T* - ω_t (φ Q ŝ'δ + φ' ŝ ĝ'δ)`` and
        ``t_n - ω_n ĝ'δ`` (the pressure of a node in contact; it may turn
        negative)."""
        _, _, proj, slipped, law, _, _ = self._linear
        pressure, trial, mean_slip, phi, dphi = law[0], law[4], law[5], law[6], law[7]
        pts = self.points
        u = pts.displacements(delta).T
        normal = proj.normal.T
        moved = np.einsum("nij,nj->ni", _slip_derivative(normal, proj.curvature, slipped), u)
        d_slip = self._project(np.stack([pts.average(c) for c in moved.T], axis=1))
        d_gap = pts.average(np.einsum("ni,ni->n", normal, u))
        lin_trial = trial - self.omega_t * (phi[:, None] * d_slip
                                            + (dphi * d_gap)[:, None] * mean_slip)
        return lin_trial, pressure - self.omega_n * d_gap

    def sticking(self, delta):
        """Force and stiffness corrections for the slipping nodes that the
        update ``delta`` would bring back into stick, in the linear model
        of the last evaluation (an active-set prediction, like
        :meth:`~RigidContact.touching` for the normal law).

        A slipping node has no tangential stiffness along its slip: the
        Newton update moves it along ``τ`` as if it were free, through
        the stick cone and, where the flow stops or turns, into slip the
        other way; the line search then finds the zero of its energy
        slope at the kink and takes a fraction of the update, iteration
        after iteration (measured on the billet: an edge node reversing
        its slip held 5-10 iterations of a step at steps 0.3-0.5).  Here
        the linearized trial ``T*(δ) = T* - ω_t (φ Q ŝ'δ + φ' ŝ ĝ'δ)`` is
        checked against the linearized cone ``μ (t_n - ω_n ĝ'δ)``: a node
        that lands inside it, or whose trial turns by more than 90°, takes
        its stick branch (``T = T*``, Eq. 4.6) in the linear model, and the
        update is solved again.  The statuses of the next iterate are the
        law's own: the converged solution is unchanged.

        Returns ``(nodes, f, K)`` (``nodes`` the mask, ``f`` and ``K`` the
        changes of force and tangent at the last evaluation) or ``None``.
        """
        if self._linear is None or not 0.0 < self.mu < np.inf:
            return None
        d, t, _, _, law, f0, K0 = self._linear
        slip, active, trial = law[2], law[3], law[4]
        candidates = slip & active & ~self._freeze.sliding
        if not candidates.any():
            return None
        lin_trial, lin_pressure = self.linearized_law(delta)
        inside = np.linalg.norm(lin_trial, axis=1) <= self.mu * np.maximum(lin_pressure, 0.0)
        turned = np.einsum("ki,ki->k", lin_trial, trial) <= 0.0
        held = candidates & (inside | turned)
        if not held.any():
            return None
        saved = (self.trial, self._normals, self._sticking_slip, self._linear)
        self._held_stick = held
        try:
            f1, K1 = self.evaluate(d, t)
        finally:
            self._held_stick = None
            self.trial, self._normals, self._sticking_slip, self._linear = saved
        return held, f1 - f0, (K1 - K0).tocsr()

    def violation(self):
        """Largest gap of a pressed node (:meth:`RigidContact._misfit`), and
        slip of a sticking node since the last converged step (or since it
        touched), at the last evaluation, over ``tolerance · h_c``
        (converged when ≤ 1)."""
        trial = self.trial
        penetration = self._misfit(trial)
        slip = 0.0
        if self.mu > 0:
            sticking = trial.active & ~trial.slip
            slip = np.linalg.norm(self._sticking_slip, axis=1)[sticking].max(initial=0.0)
        return max(penetration, slip) / (self.tolerance * self.points.spacing)
