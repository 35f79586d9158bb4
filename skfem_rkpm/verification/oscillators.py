"""Spring-mass systems for verifying time integrators: a linear system
``f_int = K d`` that :func:`~skfem_rkpm.solvers.newton.newton_steps` can
drive, the amplification matrix of the HHT-α method and its principal
roots (Hilber, Hughes & Taylor 1977), and the identification of the
frequency and damping ratio of a sampled free oscillation."""

import numpy as np
import scipy.sparse as sp

from ..solvers.time_integration import hht_parameters

__all__ = ["LinearSprings", "amplification", "principal_root", "prony"]


class _Evaluation:
    def __init__(self, f_int, K):
        self.f_int, self.K = f_int, K


class LinearSprings:
    """A linear spring system ``f_int = K d`` as a Newton problem (no basis:
    no prescribed conditions)."""

    basis = None

    def __init__(self, K):
        self.stiffness = sp.csr_matrix(K)
        if self.stiffness.shape[0] != self.stiffness.shape[1]:
            raise ValueError(f"the stiffness must be square, not {self.stiffness.shape}")
        self.N = self.stiffness.shape[0]

    def evaluate(self, d, state=None, tangent=True):
        return _Evaluation(self.stiffness @ d, self.stiffness)

    def commit(self, evaluation):
        pass


def amplification(Omega, alpha):
    """The amplification matrix of HHT-α for ``d̈ + ω² d = 0`` on
    ``(d, Δt v, Δt² a)``, ``Ω = ω Δt``: from the method's three equations at
    ``n+1``, the α-weighted equation of motion and the two Newmark updates."""
    b, g = hht_parameters(alpha)
    lhs = np.array([[(1 + alpha) * Omega**2, 0, 1], [1, 0, -b], [0, 1, -g]])
    rhs = np.array([[alpha * Omega**2, 0, 0], [1, 1, 0.5 - b], [0, 1, 1 - g]])
    return np.linalg.solve(lhs, rhs)


def principal_root(Omega, alpha):
    """``(Ω̄, ξ̄)`` of the complex pair ``λ = exp(Ω̄ (−ξ̄ ± i))`` of the
    eigenvalues of :func:`amplification` (HHT 1977's definitions of the
    algorithmic frequency and damping ratio)."""
    lam = np.linalg.eigvals(amplification(Omega, alpha))
    lam = lam[np.argmax(abs(lam.imag))]
    omega = abs(np.angle(lam))
    return omega, -np.log(abs(lam)) / omega


def prony(y, skip=50):
    """``(Ω̄, ξ̄)`` of a free damped oscillation sampled once per step: the
    least-squares ``y_(n+1) = p y_n − q y_(n−1)`` of the samples after
    ``skip`` (where HHT's third, spurious root has decayed), ``λ`` a root
    of ``λ² − p λ + q``, ``λ = exp(Ω̄ (−ξ̄ ± i))``."""
    y = np.asarray(y, dtype=float)[skip:]
    if y.size < 5:
        raise ValueError(f"need at least 5 samples after skipping {skip}, not {y.size}")
    p, q = np.linalg.lstsq(np.c_[y[1:-1], -y[:-2]], y[2:], rcond=None)[0]
    lam = np.roots([1.0, -p, q])[0]
    omega = abs(np.angle(lam))
    return omega, -np.log(abs(lam)) / omega
