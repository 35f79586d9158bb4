"""Contact of slave points with a moving rigid tool: the Newton
contribution (force and consistent tangent, Eq. 4.27-4.29) of the penalty
Coulomb law of :mod:`.friction` at the slave points of :mod:`.slave_points`
against a tool of :mod:`.tools`.

A node that comes into contact during a step counts its slip from the moment
it touches (the gap interpolated linearly over the step), so that its
tangential traction starts from zero, also when it sticks.
:class:`RigidContact` is a contribution to the Newton iterations of
:func:`skfem_rkpm.solvers.newton.newton_steps`.
"""

import numpy as np
import scipy.sparse as sp

from .friction import (DEFAULT_AUGMENTED_TOLERANCE, DEFAULT_PENALTY_FACTOR,
                       DEFAULT_TANGENTIAL_FACTOR, ContactState,
                       _positive, coulomb, default_penalty, friction_coefficient)
from .contact_status import StatusFreeze
from .problem import NonFiniteError
from .slave_points import slave_points
from .stick_prediction import sticking
from .tools import Tool

__all__ = ["RigidContact", "ToolSideError"]

#: the largest linear map from the blocks of the point tangent to the
#: entries of ``Gᵀ X G`` that :class:`_PointCoupling` builds (FEM billet_3d:
#: 405 terms; an RK basis with nodal collocation has products of two rows
#: of ``Λᵀ``, 1e3-1e4 terms per block entry, and keeps the sparse products)
PRODUCT_MAP_ENTRIES = 2_000_000


def _outer(a, b):
    return np.einsum("ni,nj->nij", a, b)


def _directional(G, vectors):
    """Rows ``v_qᵀ G_q`` (sparse n × N): the derivative of ``v_q · u(x_q)``."""
    dim, n = vectors.shape
    P = sp.csr_matrix((vectors.T.ravel(), (np.repeat(np.arange(n), dim),
                                           np.arange(dim * n))), shape=(n, dim * n))
    return (P @ G).tocsr()


def _curvature_blocks(proj, pressure, shear):
    """Per point ``∂(-(p n + s t))/∂x`` at fixed tractions ``p, s``:
    ``-p κ t tᵀ + s κ n tᵀ`` (``∂n/∂x = κ t tᵀ``, ``∂t/∂x = -κ n tᵀ``)."""
    n, t, kappa = proj.normal.T, proj.tangent.T, proj.curvature
    return ((-pressure * kappa)[:, None, None] * _outer(t, t)
            + (shear * kappa)[:, None, None] * _outer(n, t))


class _PointCoupling:
    """The fixed sparsity of the rigid-contact tangent between slave points.

    Contact nodes couple the slave points they share (``M = Nᵀ w``): the
    tangent is ``Gᵀ X G`` with ``X`` a (d × d)-block matrix on the pattern
    of ``Mᵀ M`` plus the diagonal.  The scalar matrices ``Mᵀ diag(v) M``
    are linear in the nodal values ``v``: their entries are summed from the
    products ``M_Kp M_Kq`` listed here once, so that each evaluation builds
    ``X`` from arrays and needs two sparse products only.
    """

    def __init__(self, pts, product_map=True):
        M = sp.csr_matrix(pts.weighted_hats)
        n = M.shape[1]
        pattern = (abs(M).T @ abs(M) + sp.identity(n)).tocsr()
        pattern.sort_indices()
        self.indptr, self.indices = pattern.indptr, pattern.indices
        rows = np.repeat(np.arange(n), np.diff(pattern.indptr))
        keys = rows.astype(np.int64) * n + pattern.indices
        node_of = np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))
        # every pair (p, q) of points of one contact node K
        first = np.repeat(np.arange(M.nnz), np.diff(M.indptr)[node_of])
        start = M.indptr[node_of][first]
        offset = np.arange(len(first)) - np.repeat(
            np.concatenate([[0], np.cumsum(np.diff(M.indptr)[node_of])[:-1]]),
            np.diff(M.indptr)[node_of])
        second = start + offset
        self.node = node_of[first]
        self.entry = np.searchsorted(keys, M.indices[first].astype(np.int64) * n
                                     + M.indices[second])
        self.coefficient = M.data[first] * M.data[second]
        self.rows = rows
        self.cols = pattern.indices
        self.diagonal = np.searchsorted(keys, np.arange(n, dtype=np.int64) * (n + 1))
        self.n = n
        self.G = sp.csr_matrix(pts.G)
        self.G.sort_indices()
        self.GT = self.G.T.tocsr()
        # dim -> the linear map from the blocks to Gᵀ X G, or None (products)
        self._product = {} if product_map else {2: None, 3: None}

    def scalar(self, v):
        """The entries of ``Mᵀ diag(v) M`` on the pattern."""
        return np.bincount(self.entry, weights=self.coefficient * v[self.node],
                           minlength=len(self.cols))

    def tangent(self, blocks):
        """``Gᵀ X G`` for the d × d blocks of ``X`` on the pattern.

        The entries of ``Gᵀ X G`` are linear in those of the blocks: where
        that map has at most ``PRODUCT_MAP_ENTRIES`` terms (FEM bases and
        small RK supports, whose rows of ``G`` hold a few entries), it is
        built once (:meth:`_product_map`) and each tangent is one sparse
        matrix-vector product into a fixed pattern; otherwise two sparse
        matrix products.  Both sum the same terms (in another order)."""
        dim = blocks.shape[-1]
        if dim not in self._product:
            self._product[dim] = self._product_map(dim)
        product = self._product[dim]
        if product is not None:
            T, indices, indptr = product
            return sp.csr_matrix((T @ blocks.ravel(), indices, indptr),
                                 shape=(self.G.shape[1],) * 2)
        X = sp.bsr_matrix((blocks, self.indices, self.indptr),
                          shape=(dim * self.n, dim * self.n)).tocsr()
        K = self.GT @ (X @ self.G)
        # sorted, so that the sum with the solid's tangent (canonical) takes
        # scipy's fast path and stays canonical: no sort of the larger sum
        K.sort_indices()
        return K

    def _product_map(self, dim):
        """``(T, indices, indptr)``: the CSR pattern of ``Gᵀ X G`` and the
        sparse ``T`` with ``data = T @ blocks.ravel()``, or None if ``T``
        would have more than ``PRODUCT_MAP_ENTRIES`` terms.

        Entry ``e`` of the blocks sits at row ``r`` and column ``c`` of
        ``X`` and adds ``G[r, a] X_e G[c, b]`` to entry ``(a, b)``."""
        G, N = self.G, self.G.shape[1]
        block_rows = np.repeat(np.arange(self.n), np.diff(self.indptr))
        i, j = np.divmod(np.arange(dim * dim), dim)
        r = (dim * block_rows[:, None] + i[None, :]).ravel()  # the order of blocks.ravel()
        c = (dim * self.indices[:, None] + j[None, :]).ravel()
        length = np.diff(G.indptr)
        terms = length[r] * length[c]
        if terms.sum() > PRODUCT_MAP_ENTRIES:
            return None
        e = np.repeat(np.arange(len(r)), terms)
        # the k-th term of entry e: the (k // len_c)-th entry of row r, (k % len_c)-th of c
        k = np.arange(len(e)) - np.repeat(np.cumsum(terms) - terms, terms)
        left = G.indptr[r][e] + k // length[c][e]
        right = G.indptr[c][e] + k % length[c][e]
        keys = G.indices[left].astype(np.int64) * N + G.indices[right]
        unique, place = np.unique(keys, return_inverse=True)
        T = sp.csr_matrix((G.data[left] * G.data[right], (place, e)),
                          shape=(len(unique), len(r)))
        rows, cols = np.divmod(unique, N)
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=N))])
        return T, cols.astype(np.int32), indptr.astype(np.int32)


def _rigid_tangent(coupling, proj, slipped, law, omega_n, omega_t, mu, pts):
    """Consistent tangent of the rigid-tool contact force (Eq. 4.28-4.29).

    With ``B_n``, ``B_t`` the rows ``n_qᵀ G_q``, ``t_qᵀ G_q`` of the slave
    points, ``M = Nᵀ w`` (hat functions times point weights; the diagonal
    of the weights for nodal collocation) and ``W`` the node weights, the
    nodal gap ``ĝ = W⁻¹ M g`` has the derivative ``W⁻¹ M B_n`` and

        K = ω_n B_nᵀ Mᵀ H W⁻¹ M B_n                        (normal, symmetric)
          + ω_t B_tᵀ Mᵀ S φ W⁻¹ M a B_t                    (stick)
          + ω_t B_tᵀ Mᵀ S Δĝ_t φ' W⁻¹ M B_n                (stick, touching)
          + μ ω_n B_tᵀ Mᵀ sgn(t_t) Σ W⁻¹ M B_n             (slip, non-symmetric)
          + Gᵀ w (-p κ t tᵀ + s κ n tᵀ) G                  (curved masters)

    ``H``, ``S``, ``Σ`` select the nodes in contact, sticking and slipping,
    ``a_q = 1 - κ_q (Δξ_q·n_q)`` comes from the rotation of ``t`` and
    ``φ(ĝ)`` is the part of the step spent in contact (:meth:`RigidContact._law`).
    All terms are ``Gᵀ X G`` with ``X`` in 2 × 2 blocks between slave points
    (:class:`_PointCoupling`), summed before the two sparse products.
    """
    pressure, shear, slip, active, slip_t, phi, dphi = law
    inv_W = 1.0 / pts.node_weights
    normal, tangent = proj.normal.T, proj.tangent.T
    p, q = coupling.rows, coupling.cols
    blocks = ((omega_n * coupling.scalar(active * inv_W))[:, None, None]
              * normal[p][:, :, None] * normal[q][:, None, :])
    if mu > 0:
        a = 1.0 - proj.curvature * np.einsum("ni,ni->n", slipped, normal)
        stick = omega_t * (active & ~slip) * inv_W
        coupled = coupling.scalar(stick * slip_t * dphi)
        if np.isfinite(mu):  # μ = ∞ (exact stick) never slips
            coupled = coupled + coupling.scalar(
                mu * omega_n * np.sign(shear) * (slip & active) * inv_W)
        blocks += ((coupling.scalar(stick * phi) * a[q])[:, None, None]
                   * tangent[p][:, :, None] * tangent[q][:, None, :])
        blocks += coupled[:, None, None] * tangent[p][:, :, None] * normal[q][:, None, :]
    blocks[coupling.diagonal] += pts.weights[:, None, None] * _curvature_blocks(
        proj, pts.hats @ pressure, pts.hats @ shear)
    return coupling.tangent(blocks)


def _touch_fraction(gap, previous_gap, was_active):
    """Part ``φ`` of the step that a node spends in contact, by linear
    interpolation of its gap from the last converged step, and ``dφ/dĝ``.

    ``φ = 1`` for nodes already in contact; for a node that touches during
    the step ``φ = -ĝ / (ĝ_0 - ĝ)``, so that its slip is counted from the
    moment it touches and its tangential traction starts from zero."""
    g0 = np.where(was_active, 0.0, np.maximum(previous_gap, 0.0))
    depth = np.maximum(-gap, 0.0)
    span = g0 + depth
    safe = np.where(span > 0, span, 1.0)
    phi = np.where(span > 0, depth / safe, 1.0)
    dphi = np.where((span > 0) & (gap < 0), -g0 / safe**2, 0.0)
    return phi, dphi


class ToolSideError(ValueError):
    """A tool starts with the part on its back side: every slave point behind
    its surface at t = 0, deeper than the particle spacing somewhere (its
    normal or orientation is the wrong way round).  ``what`` names the
    tool's data to change, ``fix`` how, ``detail`` the gaps found."""

    def __init__(self, what, fix, detail, name):
        super().__init__(f"the {what} of tool {name!r} {fix} ({detail})")
        self.what, self.fix, self.detail = what, fix, detail


def _check_initial_side(tool, X, spacing):
    """Raise :class:`ToolSideError` if the tool starts on the wrong side of
    the reference slave points ``X``: none has a positive gap at t = 0 and
    the deepest is behind the surface by more than the particle ``spacing``
    (a part that merely touches a tool has gaps of 0; a real initial
    overlap of a whole spacing or more is not a forming set-up either)."""
    gap = tool.project(X, 0.0).gap
    tol = 1e-9 * spacing
    if gap.max() > tol or gap.min() >= -spacing:
        return
    from .tools import Arc, Platen

    if isinstance(tool, Platen):
        what, fix = "normal", "points away from the part; flip it"
    elif isinstance(tool, Arc):
        what, fix = "angles", ("run the wrong way (the part must be on the arc's left); "
                               "swap start and end")
    else:
        what, fix = "points", ("run the wrong way (the part must be on their left); "
                               "reverse their order")
    raise ToolSideError(what, fix, f"at t = 0 all {gap.size} slave points are behind its "
                        f"surface, up to {-gap.min():.4g} deep, "
                        f"{-gap.min() / spacing:.3g} particle spacings", tool.name)


def _warn_if_out_of_reach(tool, X, spacing, samples=21):
    """Warn if ``tool`` stays clear of the reference points ``X`` at every
    load factor of ``[0, 1]`` (sampled): a misplaced tool or a motion in the
    wrong direction; or if it starts in contact (a gap within 1e-9 of the
    particle ``spacing``) and its gap only grows: a motion away from the
    part.  Only warnings: loads may still deform the part onto it."""
    import warnings

    gaps = np.array([tool.project(X, t).gap.min() for t in np.linspace(0.0, 1.0, samples)])
    k = int(np.argmin(gaps))
    if gaps[k] > 0:
        warnings.warn(f"tool {tool.name!r} does not reach the part during its motion: the "
                      f"smallest gap to the undeformed slave boundary is {gaps[k]:.4g} "
                      f"(at t = {k / (samples - 1):g}); unless other loads deform the part "
                      "onto it, it carries no force; check its position and motion",
                      stacklevel=3)
    elif (gaps[0] <= 1e-9 * spacing and np.all(np.diff(gaps) >= 0)
          and gaps[-1] > 1e-9 * spacing):
        warnings.warn(f"tool {tool.name!r} starts in contact with the part and moves away "
                      f"from it: the smallest gap to the undeformed slave boundary grows "
                      f"from {gaps[0]:.4g} at t = 0 to {gaps[-1]:.4g} at t = 1; unless "
                      "other loads push the part after it, it carries no force; check the "
                      "sign of its motion", stacklevel=3)


def _check_finite_traction(traction, X, name):
    """NonFiniteError naming the first slave point with a NaN or inf traction."""
    finite = np.isfinite(traction).all(axis=0)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise NonFiniteError(
            f"the contact traction of tool {name!r} is not finite at {bad.size} slave "
            f"points; first at X = ({', '.join(f'{c:.4g}' for c in X[:, bad[0]])})", bad)


class RigidContact:
    """Penalty frictional contact of a body with a rigid moving tool
    (Sec. 4.3, Eq. 4.25-4.29), a contribution for
    :func:`skfem_rkpm.solvers.newton.newton_steps`.

    The contact law (Eq. 4.5-4.6) acts at the boundary particles.  With
    ``collocation="nodal"`` it sees the gap and slip of the particle itself
    (the paper).  With ``"quadrature"`` it sees their averages over the
    boundary Gauss points, weighted by the particle's boundary hat function
    ``N_K``, and its tractions are interpolated back with the hat
    functions and integrated at the Gauss points,
    ``f_I = Σ_q w_q Ψ_I(x_q) t(x_q)``: a uniform traction is then
    integrated exactly (homogeneous states stay exact for RK bases), with
    one contact law per particle, as in the nodal case.

    Parameters
    ----------
    problem : SolidProblem
        Supplies the basis, the model and Young's modulus.
    tool : Tool
    slaves : str, sequence of str, facet indices, or None
        Boundaries whose points may touch the tool (default: all).
    friction : float or "stick"
        Coulomb coefficient ``μ`` (0: frictionless) or ``"stick"`` (:func:`friction_coefficient`).
    collocation : {"nodal", "quadrature", "gauss"}
        See :func:`slave_points`.
    penalty : float, optional
        Normal penalty ``ω_n`` per unit area; default
        ``factor · E / h_c`` (:func:`default_penalty`).
    tangential_penalty : float, optional
        ``ω_t`` per unit area; default ``tangential_factor · E / h_c``.
    factor, tangential_factor : float
        Factors of the default penalties.
    intorder : int, optional
        Facet quadrature degree for ``collocation="quadrature"``.
    enforcement : {"penalty", "augmented"}
        The paper's penalty law, or the augmented Lagrangian: the penalty law
        around multipliers that :meth:`augment` updates after each converged
        Newton solve (Uzawa), until the gap of the pressed nodes (penetration
        or distance) is below ``tolerance · h_c`` and the sticking nodes slip less than
        that; ``friction="stick"`` is then ``μ = ∞``.
    tolerance : float
        Gap of a pressed node and stick slip allowed by the augmented Lagrangian, as a
        fraction of the particle spacing ``h_c`` along the contact boundary.
    """

    def __init__(self, problem, tool, slaves=None, friction=0.0, collocation="nodal",
                 penalty=None, tangential_penalty=None, factor=DEFAULT_PENALTY_FACTOR,
                 tangential_factor=DEFAULT_TANGENTIAL_FACTOR, intorder=None,
                 enforcement="penalty", tolerance=DEFAULT_AUGMENTED_TOLERANCE):
        self._check_tool(tool, problem)
        if enforcement not in ("penalty", "augmented"):
            raise ValueError(f"enforcement must be 'penalty' or 'augmented', not "
                             f"{enforcement!r}")
        self.problem, self.tool, self.name = problem, tool, tool.name
        self.enforcement = enforcement
        self.mu = friction_coefficient(friction, exact_stick=enforcement == "augmented")
        self.collocation = collocation
        self.points = slave_points(problem.basis, slaves, collocation, problem.model,
                                   intorder)
        self.omega_n = (default_penalty(problem.material.E, self.points.spacing, factor)
                        if penalty is None else _positive(penalty, "penalty"))
        self.omega_t = (default_penalty(problem.material.E, self.points.spacing,
                                        tangential_factor)
                        if tangential_penalty is None
                        else _positive(tangential_penalty, "tangential penalty"))
        self.tolerance = _positive(tolerance, "augmented Lagrangian tolerance")
        self._coupling = _PointCoupling(self.points, self._PRODUCT_MAP)
        # only exact stick freezes (measured: with μ = 0.1 the freeze cost the
        # coarse cup draw a cut-back, and finite μ ends grazing by slipping)
        self._freeze = StatusFreeze(self.points.m, enabled=(enforcement == "augmented"
                                                             and self.mu == np.inf))
        self._held_stick = None  # nodes held in stick by sticking() (a linear model)
        self._linear = None  # (d, t, proj, slipped, law, f, K) of the last evaluation
        self.state = self.trial = self._initial_state()
        self.restart()
        self._check_start()
        _warn_if_out_of_reach(tool, self.points.X, self.points.spacing)

    #: sum the tangent through :meth:`_PointCoupling._product_map` (3D); in 2D
    #: the sparse products cost little (0.2 ms on the ring), and the map's
    #: other order of the same sums moved the stick ring's hardest step
    #: (step 95) by one iteration
    _PRODUCT_MAP = False

    def _check_tool(self, tool, problem):
        """TypeError unless ``tool`` is a 2D :class:`Tool`."""
        if not isinstance(tool, Tool):
            raise TypeError(f"tool must be a Tool (Platen, Polyline, Arc), not {tool!r}")

    def _check_start(self):
        """:class:`ToolSideError` if the tool starts on the wrong side."""
        _check_initial_side(self.tool, self.points.X, self.points.spacing)

    def _initial_state(self):
        X, m = self.points.X, self.points.m
        proj = self.tool.project(X, 0.0)
        relative = X - self.tool.translation(0.0)[:, None]
        return ContactState(X.copy(), proj.gap, proj.normal, proj.tangent, relative,
                            self.points.average(proj.gap), np.zeros(m), np.zeros(m),
                            np.zeros(m, bool), np.zeros(m, bool), np.zeros(2))

    def _law(self, proj, slipped):
        """Nodal tractions (Eq. 4.5-4.6, 4.11) from the nodal gap ``ĝ`` and
        slip ``Δĝ_t`` (the particle's own, or hat-weighted averages of the
        Gauss point values ``g_n`` and ``Δg_t = Δξ·t``):
        ``t_n = ω_n ⟨-ĝ⟩``, the trial ``t_t,n - ω_t φ Δĝ_t`` with the part
        ``φ`` of the step spent in contact, and Coulomb's return map.  The
        augmented Lagrangian takes ``t_n = ⟨λ_n - ω_n ĝ⟩`` and ``λ_t`` for
        ``t_t,n`` (:meth:`augment`)."""
        pts, state = self.points, self.state
        node_gap = pts.average(proj.gap)
        pressed = node_gap - self.multipliers[0] / self.omega_n  # Eq. 4.5 around λ_n
        active, pressure = self._normal_law(pressed)
        slip_t = pts.average(np.einsum("ni,ni->n", slipped, proj.tangent.T))
        phi, dphi = _touch_fraction(node_gap, state.node_gap, state.active)
        shear, slip = self._freeze.release(*coulomb(
            pressure, self.multipliers[1] - self.omega_t * phi * slip_t, self.mu))
        if self._held_stick is not None:  # the stick branch of sticking()'s nodes
            shear = np.where(self._held_stick, self.multipliers[1] - self.omega_t * phi
                             * slip_t, shear)
            slip = slip & ~self._held_stick
        law = (pressure, np.where(active, shear, 0.0), slip & active, active, slip_t, phi,
               dphi)
        return node_gap, law

    def _normal_law(self, pressed):
        """Contact mask and pressure ``t_n = ω_n ⟨-(ĝ - λ_n/ω_n)⟩`` (Eq. 4.5)
        from ``pressed = ĝ - λ_n/ω_n``; a node frozen closed
        (:class:`~skfem_rkpm.mechanics.contact_status.StatusFreeze`) is held
        bilaterally, ``t_n = -ω_n pressed`` of either sign, one frozen open
        carries nothing."""
        active = self._freeze.apply(pressed <= 0.0)
        return active, self.omega_n * np.where(active, -pressed, 0.0)

    def evaluate(self, d, t, tangent=True):
        """Contact force (added to the internal force) and its tangent at
        coefficients ``d`` and load factor ``t``; ``tangent=False`` skips the
        tangent (None), for explicit time steps that need the force only."""
        pts = self.points
        x = pts.X + pts.displacements(d)
        proj = self.tool.project(x, t)
        relative = x - self.tool.translation(t)[:, None]
        slipped = (relative - self.state.relative).T
        node_gap, law = self._law(proj, slipped)
        pressure, shear = law[0], law[1]
        traction = (pts.hats @ pressure) * proj.normal + (pts.hats @ shear) * proj.tangent
        _check_finite_traction(traction, pts.X, self.name)
        f = self._coupling.GT @ (-(pts.weights * traction)).T.ravel()
        K = _rigid_tangent(self._coupling, proj, slipped, law, self.omega_n, self.omega_t,
                           self.mu, pts) if tangent else None
        self._normals = proj.normal  # for touching(): the linearized gaps
        self.trial = ContactState(x, proj.gap, proj.normal, proj.tangent, relative,
                                  node_gap, pressure, shear, law[2], law[3],
                                  (pts.weights * traction).sum(axis=1), t)
        self._linear = (d, t, proj, slipped, law, f, K)
        return f, K

    def sticking(self, delta):
        """The slipping nodes that the update ``delta`` brings into stick, with
        the force and stiffness changes of their stick branch in the linear
        model (:func:`~skfem_rkpm.mechanics.stick_prediction.sticking`)."""
        return sticking(self, delta)

    def touching(self, delta):
        """Penalty force and stiffness of the contact nodes that the update
        ``delta`` would bring into contact, in the linear model of the last
        evaluation.

        A node that is apart at the last evaluation has no stiffness in
        the tangent, so a Newton update may push it deep into the tool (a
        die node under a punch stroke).  Its linearized gap after the
        update is ``ĝ + Ĝ δ`` with ``Ĝ = W⁻¹ M B_n``; if that is negative,
        the normal law of Eq. (4.5) acts in the linear model as the force
        ``ω_n Ĝᵀ W ĝ`` plus the stiffness ``ω_n Ĝᵀ W Ĝ``, which
        :func:`skfem_rkpm.solvers.newton.newton_steps` adds before it solves again
        (an active-set iteration).  Returns ``(nodes, f, K)`` (``nodes`` a
        boolean mask of the touching nodes) or ``None`` if no node is
        predicted to touch.
        """
        apart = ~self.trial.active & ~self._freeze.held
        if not apart.any():
            self._freeze.predict(apart)
            return None
        pts = self.points
        pressed = self.trial.node_gap - self.multipliers[0] / self.omega_n
        # Ĝ δ from the point displacements G δ: no sparse rows unless a node touches
        moved = np.einsum("in,in->n", self._normals, pts.displacements(delta))
        touching = apart & (pressed + pts.average(moved) < 0.0)
        self._freeze.predict(touching)
        if not touching.any():
            return None
        normal_rows = _directional(pts.G, self._normals)
        rows = (pts.weighted_hats @ normal_rows) / pts.node_weights[:, None]
        scale = self.omega_n * pts.node_weights * touching
        f = rows.T @ (scale * pressed)
        K = rows.T @ sp.diags(scale) @ rows
        return touching, f, K.tocsr()

    def status_changes(self):
        """Contact nodes whose status (touching; slipping) differs between the
        last evaluation and the last converged state."""
        old, new = self.state, self.trial
        return int(np.count_nonzero((old.active != new.active) | (old.slip != new.slip)))

    def restart(self, t=None):
        """Multipliers ``(λ_n, λ_t)`` of the step from the converged state:
        ``λ_t = t_t,n`` (Eq. 4.6); ``λ_n = t_n`` for the augmented Lagrangian
        (a warm start), 0 for the penalty law.  Forgets the augmentations and
        frozen statuses of an attempt that failed.

        With the augmented Lagrangian and the load factor ``t`` of the step,
        the warm start is extrapolated along the last step's rates of the
        tractions, ``λ = t_n + (t - t_n,state) ṫ_n`` (the same predictor as
        Newton's ``d + Δt ḋ``, with ``λ_n ≥ 0``): the multipliers of the
        converged step then move with the load, and the updates of
        :meth:`augment` only correct the change of that rate (measured on
        the 3D billet, its first 20 of 50 steps: the first solve of a step
        leaves 1.7-4.4 instead of 7-8 times the tolerance, 115 instead of
        143 Newton iterations).  The
        multipliers are only the start of the Uzawa updates: the converged
        step is the same to their tolerance."""
        state = self.state
        augmented = self.enforcement == "augmented"
        normal = (np.maximum(state.pressure, 0.0) if augmented
                  else 0.0 * state.pressure)  # a frozen node's tension is not carried on
        shear = state.shear.copy()
        if augmented and t is not None and t > state.t:
            lead = t - state.t
            normal = np.maximum(normal + lead * state.pressure_rate, 0.0)
            shear = shear + lead * state.shear_rate
        self.multipliers = (normal.copy(), shear)
        self._freeze.reset()

    def watch_status(self):
        """At an accepted Newton iterate (the last evaluation): freeze the
        contact status of grazing nodes, those that flipped between open
        and closed and back, or that :meth:`touching` predicted in contact
        three iterations in a row without the iterate reaching the tool
        (exact stick, μ = ∞ with the augmented Lagrangian, only;
        :mod:`.contact_status`).  Returns the number of nodes newly frozen;
        the last evaluation is then stale."""
        return self._freeze.observe(self.trial.active)

    def review_status(self):
        """After each converged solve (with the multiplier update):
        correct frozen statuses that contradict Eq. (4.5), a frozen-closed
        node pulled by a tension above ``ω_n · tolerance · h_c`` (the
        pressure of a penetration at the tolerance) is opened (its ``λ_n``
        set to 0), a frozen-open node penetrating more than ``tolerance ·
        h_c`` (closed it pulled, open it penetrates) slides without
        friction for the rest of the attempt (:meth:`gauges` reports these
        nodes).  Returns the number of nodes changed (the step is then solved
        again)."""
        gap_tolerance = self.tolerance * self.points.spacing
        corrected = self._freeze.review(self.trial.node_gap, self.trial.pressure,
                                        gap_tolerance, self.omega_n * gap_tolerance)
        self.multipliers[0][corrected] = 0.0
        return int(np.count_nonzero(corrected))

    def violation(self):
        """Largest gap of a pressed node (:meth:`_misfit`), and slip of a
        sticking node since the last converged step (or since it touched),
        at the last evaluation, over ``tolerance · h_c`` (the augmented
        Lagrangian has converged when ≤ 1)."""
        trial = self.trial
        penetration = self._misfit(trial)
        slip = 0.0
        if self.mu > 0:
            sticking = trial.active & ~trial.slip
            moved = (trial.relative - self.state.relative).T
            slip_t = self.points.average(np.einsum("ni,ni->n", moved, trial.tangent.T))
            phi, _ = _touch_fraction(trial.node_gap, self.state.node_gap, self.state.active)
            slip = np.abs(phi * slip_t)[sticking].max(initial=0.0)
        return max(penetration, slip) / (self.tolerance * self.points.spacing)

    def _misfit(self, trial):
        """Largest gap ``|ĝ|`` of a pressed node, penetrating or not: a
        node pressed from a distance (``0 < ĝ < λ_n/ω_n``, a multiplier
        above the pressure it ends with, e.g. extrapolated by
        :meth:`restart` when the load stops rising) is as far from the
        contact law as one that penetrates; a node frozen closed is held
        on the tool, so its gap counts either way too."""
        return np.abs(trial.node_gap)[trial.active].max(initial=0.0)

    def augment(self):
        """One Uzawa update of the augmented Lagrangian after a converged
        Newton solve: the multipliers take the tractions found, ``λ_n = t_n``
        and ``λ_t = t_t`` (return-mapped), while gaps and slips still count
        from the last converged step, so that sticking nodes end the step
        where they started on the tool.  Returns False (and changes nothing)
        for the penalty law or when :meth:`violation` ≤ 1."""
        if self.enforcement != "augmented" or self.violation() <= 1.0:
            return False
        self.multipliers = (self.trial.pressure.copy(), self.trial.shear.copy())
        return True

    def commit(self):
        """Accept the last evaluation as the converged state (Eq. 4.11),
        with the rates of its tractions over the step (augmented Lagrangian,
        nodes in contact at both ends of the step; :meth:`restart`)."""
        old, new = self.state, self.trial
        if self.enforcement == "augmented" and new.t > old.t:
            both = old.active & new.active & ~self._freeze.held & ~self._freeze.sliding
            rows = both.reshape((-1,) + (1,) * (new.shear.ndim - 1))
            new.pressure_rate = np.where(both, (new.pressure - old.pressure)
                                         / (new.t - old.t), 0.0)
            new.shear_rate = np.where(rows, (new.shear - old.shear) / (new.t - old.t), 0.0)
        self.state = new
        self.restart()

    def resultants(self):
        """``{tool name: (Fx, Fy)}``, the force of the tool on the body."""
        return {self.name: self.state.force.copy()}

    def penetration(self):
        """Largest penetration ``max(-g_n, 0)`` at the last evaluation."""
        return self.trial.penetration

    def gauges(self, t):
        """Tool translation (a 3D surface's prescribed ``displacement``, without
        the swing of a rotation) and penetration, for output tables."""
        dx = getattr(self.tool, "displacement", self.tool.translation)(t)
        out = {f"{self.name} d{c}": float(v) for c, v in zip("xyz", dx)}
        out[f"{self.name} penetration"] = self.penetration()
        if self._freeze.enabled:
            # only a node held closed by the freeze can pull; only one released
            # by it slides under μ = ∞
            state = self.state
            out[f"{self.name} tension"] = float(max(-state.pressure.min(initial=0.0), 0.0))
            out[f"{self.name} sliding"] = int(np.count_nonzero(state.slip & state.active))
        return out

    def get_state(self):
        """The committed state (for checkpoints)."""
        return self.state

    def set_state(self, state):
        """Restore a state returned by :meth:`get_state`."""
        if state.gap.shape != (self.points.n,) or state.shear.shape != self.state.shear.shape:
            raise ValueError("the state belongs to a contact with different slave points")
        self.state = self.trial = state
        self.restart()


