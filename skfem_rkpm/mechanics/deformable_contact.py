"""Frictionless contact between two deformable boundaries of one mesh:
node-to-segment, Eq. (4.13)-(4.19) of Chen, Pan, Roque & Wang (1998).
"""

import numpy as np
import scipy.sparse as sp

from ..approximation.constraints import transformation
from .friction import DEFAULT_PENALTY_FACTOR, ContactState, _positive, default_penalty
from .rigid_contact import _outer
from .slave_points import _check_model, _facets, _interleaved, _nodal_points
from .tools import _left

__all__ = ["NodeToSegmentContact"]

# ---------------------------------------------------------------------------
# two deformable bodies: node-to-segment contact, Eq. (4.13)-(4.19)
# ---------------------------------------------------------------------------


def _oriented_segments(mesh, facets):
    """Master facets as node pairs ``(M1, M2)`` ordered so that ``e_3 × t``
    points out of the master body (away from the adjacent cell)."""
    seg = mesh.facets[:, facets].T.copy()
    cells = mesh.f2t[0, facets]
    centroid = mesh.p[:, mesh.t[:, cells]].mean(axis=1).T
    a, b = mesh.p[:, seg[:, 0]].T, mesh.p[:, seg[:, 1]].T
    flip = np.einsum("nk,nk->n", _left(b - a), 0.5 * (a + b) - centroid) < 0
    seg[flip] = seg[flip][:, ::-1]
    return seg


def _closest_segments(xs, a, b):
    """Per slave point (n, 2) the closest segment ``a → b`` (m, 2): index,
    natural coordinate ``α`` (Eq. 4.8, unclamped), gap (Eq. 4.10), length,
    tangent and normal (Eq. 4.7)."""
    e = b - a
    length = np.linalg.norm(e, axis=1)
    t = e / length[:, None]
    alpha = np.einsum("nmk,mk->nm", xs[:, None, :] - a[None], t) / length[None]
    cp = a[None] + np.clip(alpha, 0.0, 1.0)[..., None] * e[None]
    k = np.argmin(np.linalg.norm(xs[:, None, :] - cp, axis=-1), axis=1)
    rows = np.arange(xs.shape[0])
    n = _left(t)[k]
    gap = np.einsum("nk,nk->n", xs - a[k], n)
    return k, alpha[rows, k], gap, length[k], t[k], n


def _composite_vectors(alpha, t, n):
    """``C_n``, ``T``, ``P`` of Eq. (4.16), (4.23), (4.21), each (n, 6)
    in the order of Eq. (4.14): slave, M1, M2."""
    a = alpha[:, None]
    zero = np.zeros_like(n)
    Cn = np.hstack([n, -(1 - a) * n, -a * n])
    T = np.hstack([t, -(1 - a) * t, -a * t])
    P = np.hstack([zero, -n, n])
    return Cn, T, P


def _node_to_segment_tangent(Cn, T, P, gap, length, omega):
    """Frictionless part of Eq. (4.19):
    ``ω C_n C_nᵀ + (λ_n / l)(P Tᵀ + T Pᵀ + (g_n / l) P Pᵀ)``, ``λ_n = -ω g_n``."""
    lam = -omega * gap
    return (omega * _outer(Cn, Cn)
            + (lam / length)[:, None, None]
            * (_outer(P, T) + _outer(T, P) + (gap / length)[:, None, None] * _outer(P, P)))


def _scatter_composite(dofs, f_hat, K_hat, N):
    """Nodal force vector and stiffness (N, N) from the composite vectors
    (n, 6) and matrices (n, 6, 6) of Eq. (4.14)-(4.19) on nodal ``dofs``."""
    f = np.bincount(dofs.ravel(), weights=f_hat.ravel(), minlength=N)
    rows = np.repeat(dofs, dofs.shape[1], axis=1).ravel()
    cols = np.tile(dofs, (1, dofs.shape[1])).ravel()
    return f, sp.csr_matrix((K_hat.ravel(), (rows, cols)), shape=(N, N))


class NodeToSegmentContact:
    """Frictionless penalty contact between two deformable bodies of one
    basis (Eq. 4.13-4.19): the slave particles of one boundary against the
    segments between the current positions of the master boundary particles.

    For RK bases the shape functions of one body must not reach into the
    other (supports do not see the mesh): keep the bodies apart in the
    reference configuration by more than the support radius.

    Parameters
    ----------
    problem : SolidProblem
    slave, master : str, sequence of str or facet indices
        The two boundaries.
    penalty : float, optional
        ``ω_n`` per unit area; default :func:`default_penalty`.
    factor : float
        Penalty factor of the default.
    extension : float
        A slave particle whose projection falls at most this fraction of a
        segment length beyond the segment's ends (``-e ≤ α ≤ 1 + e``) is
        still in contact with it: the corner particles of a slave surface
        then do not chatter in and out of contact at the end of the master
        surface or at a convex master vertex.
    name : str
        Key of the force in :meth:`resultants`.

    Notes
    -----
    A slave particle is in contact when its gap (Eq. 4.10) on the closest
    master segment is negative and its natural coordinate (Eq. 4.8) lies in
    ``[-e, 1 + e]``.
    """

    def __init__(self, problem, slave, master, penalty=None,
                 factor=DEFAULT_PENALTY_FACTOR, extension=0.1, name="contact"):
        basis = problem.basis
        if not (np.isfinite(extension) and 0 <= extension < 0.5):
            raise ValueError(f"extension must lie in [0, 0.5), not {extension!r}")
        self.extension = float(extension)
        _check_model(basis, problem.model)
        if problem.model == "3d":
            raise ValueError("contact between deformable bodies is implemented in 2D "
                             "(node to segment) only; in 3D use rigid tools")
        self.problem, self.name = problem, name
        mesh = basis.mesh
        self.slaves = _nodal_points(basis, _facets(mesh, slave),
                                    problem.model == "axisymmetric")
        self.segments = _oriented_segments(mesh, _facets(mesh, master))
        if np.intersect1d(self.slaves.nodes, self.segments).size:
            raise ValueError("slave and master boundaries share particles")
        self.omega = (default_penalty(problem.material.E, self.slaves.spacing, factor)
                      if penalty is None else _positive(penalty, "penalty"))
        self.Lt = sp.csr_matrix(transformation(basis))
        self.state = self.trial = None

    def _positions(self, d):
        """Current nodal positions ``X + û`` (2, nnodes), ``û = Λᵀ d``."""
        mesh = self.problem.basis.mesh
        return mesh.p + (self.Lt @ d).reshape(-1, 2).T

    def evaluate(self, d, t):
        """Contact force and tangent at coefficients ``d`` (``t`` unused)."""
        x = self._positions(d)
        s = self.slaves.nodes
        m1, m2 = self.segments[:, 0], self.segments[:, 1]
        k, alpha, gap, length, tan, nrm = _closest_segments(x[:, s].T, x[:, m1].T,
                                                            x[:, m2].T)
        reach = self.extension
        active = (gap <= 0) & (alpha >= -reach) & (alpha <= 1 + reach)
        Cn, T, P = _composite_vectors(alpha, tan, nrm)
        w = self.slaves.weights * active
        lam = self.omega * np.maximum(-gap, 0.0)
        f_hat = -(w * lam)[:, None] * Cn  # Eq. (4.15): f̂ = λ_n C_n, as internal force
        K_hat = w[:, None, None] * _node_to_segment_tangent(Cn, T, P, gap, length,
                                                             self.omega)
        dofs = np.hstack([_interleaved(nodes).reshape(-1, 2) for nodes in (s, m1[k], m2[k])])
        fn, Kn = _scatter_composite(dofs, f_hat, K_hat, self.Lt.shape[0])
        gap = np.where(active, gap, np.inf)  # no contact beyond the master ends
        self.trial = ContactState(x[:, s], gap, nrm.T, tan.T, x[:, s], gap, lam * active,
                                  np.zeros_like(gap), np.zeros(len(s), bool), active,
                                  ((w * lam)[:, None] * nrm).sum(axis=0))
        return self.Lt.T @ fn, (self.Lt.T @ Kn @ self.Lt).tocsr()

    def commit(self):
        """Accept the last evaluation (frictionless: no history)."""
        self.state = self.trial

    def resultants(self):
        """``{name: (Fx, Fy)}``, the force of the master body on the slave body."""
        return {self.name: (np.zeros(2) if self.state is None else self.state.force.copy())}

    def penetration(self):
        """Largest penetration of a slave particle at the last evaluation."""
        return 0.0 if self.trial is None else self.trial.penetration


# ---------------------------------------------------------------------------
