"""Finite-strain J2 plasticity: logarithmic elastic strain, exponential return map.

The hyperelastic-based multiplicative model the paper recommends (Simo 1992;
Eq. 3.8 names the hypoelastic alternative).  With the plastic state stored as
``C_p⁻¹`` and the accumulated plastic strain ``ε̄ᵖ``:

1. trial elastic left Cauchy-Green tensor ``b_e = F C_p⁻¹ Fᵀ``;
2. trial elastic logarithmic strain ``ε_e = ½ ln b_e`` (spectral);
3. the small-strain J2 radial return on ``ε_e`` with isotropic elasticity
   gives the Kirchhoff stress ``τ`` and ``ε̄ᵖ``;
4. ``b_e = exp(2 ε_e)`` is pulled back into ``C_p⁻¹ = F⁻¹ b_e F⁻ᵀ``.

The return is exact for proportional loading, whatever the step size, and the
model is objective by construction.  The consistent tangent of the first
Piola-Kirchhoff stress ``P = τ F⁻ᵀ``,

    A_iJkL = ½ (D : L : B)_ijkl F⁻¹_Jj F⁻¹_Ll - τ_il F⁻¹_Jk F⁻¹_Ll,

chains the small-strain consistent tangent ``D``, the derivative ``L`` of the
tensor logarithm and ``B_ijkl = δ_ik b_jl + δ_jk b_il`` (de Souza Neto, Perić
& Owen 2008, Sect. 14.5), so Newton's method converges quadratically.

Arrays hold one 3x3 tensor per point: shape (n, 3, 3); 4th-order tensors
(n, 3, 3, 3, 3).  Plane strain and axisymmetric models use the same 3x3
algebra with their out-of-plane entries.
"""

from dataclasses import dataclass

import numpy as np

from .eigen3 import symmetric_eigen
from .kinematics import inverse_and_determinant

__all__ = ["Hardening", "perfect", "linear", "swift", "voce", "table", "J2Material",
           "MaterialState", "ReturnMapError", "ReturnPoint"]

I3 = np.eye(3)
#: the shear pairs (A, B), A < B, of principal components
_PAIR_A, _PAIR_B = np.array([0, 0, 1]), np.array([1, 2, 2])
#: the nine entries (i, J) of a 3x3 tensor in row-major order
_ALL_ROWS, _ALL_COLS = np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3)


class ReturnMapError(RuntimeError):
    """The return map failed at some points (``points``: their indices)."""

    def __init__(self, message, points):
        super().__init__(message)
        self.points = points


@dataclass(frozen=True)
class Hardening:
    """Yield stress ``σ_y(ε̄ᵖ)`` and its slope ``H = dσ_y/dε̄ᵖ``."""

    name: str
    stress: callable
    slope: callable

    def __call__(self, alpha):
        return self.stress(alpha), self.slope(alpha)


def _number(value, name, low=0.0, strict=True):
    """``value`` as a finite float above ``low``; a ValueError naming it otherwise."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = None
    ok = x is not None and not isinstance(value, (bool, np.bool_)) and np.isfinite(x)
    if not ok or not (x > low if strict else x >= low):
        relation = ">" if strict else ">="
        raise ValueError(f"{name} must be a finite number {relation} {low:g}, not {value!r}")
    return x


def perfect(sigma_y):
    """Perfect plasticity, ``σ_y`` constant."""
    sigma_y = _number(sigma_y, "yield stress")
    return Hardening("perfect", lambda a: sigma_y + 0.0 * a, lambda a: 0.0 * a)


def linear(sigma_y, H):
    """Linear isotropic hardening ``σ_y + H ε̄ᵖ`` (``H >= 0``)."""
    sigma_y = _number(sigma_y, "yield stress")
    H = _number(H, "hardening modulus H", strict=False)
    return Hardening("linear", lambda a: sigma_y + H * a, lambda a: H + 0.0 * a)


def swift(K, eps0, n):
    """Swift power law ``K (ε₀ + ε̄ᵖ)ⁿ`` (the paper's sheet: 589 (1e-4 + ε̄ᵖ)^0.216 MPa)."""
    try:
        K, eps0, n = (_number(v, name) for v, name in ((K, "K"), (eps0, "eps0"), (n, "n")))
    except ValueError as err:
        raise ValueError(f"Swift law needs K > 0, eps0 > 0, n > 0: {err}") from None
    if not K * eps0 ** n > 0:
        raise ValueError(f"Swift law: the initial yield stress K eps0^n = {K * eps0 ** n:g} "
                         f"underflows (K = {K}, eps0 = {eps0}, n = {n}); use a smaller n "
                         "or a larger eps0")
    return Hardening("swift", lambda a: K * (eps0 + np.maximum(a, 0.0)) ** n,
                     lambda a: K * n * (eps0 + np.maximum(a, 0.0)) ** (n - 1.0))


def voce(sigma_y, Q, b, H=0.0):
    """Voce saturation law ``σ_y + Q (1 - exp(-b ε̄ᵖ)) + H ε̄ᵖ``.

    The yield stress rises by ``Q`` at the rate ``b`` and saturates at
    ``σ_y + Q``; the optional linear term ``H ε̄ᵖ`` keeps a slope at large
    strains (``Q, b, H >= 0``).
    """
    sigma_y = _number(sigma_y, "yield stress")
    Q = _number(Q, "Voce saturation stress Q", strict=False)
    b = _number(b, "Voce rate b", strict=False)
    H = _number(H, "hardening modulus H", strict=False)
    return Hardening(
        "voce",
        lambda a: sigma_y + Q * -np.expm1(-b * np.maximum(a, 0.0)) + H * a,
        lambda a: Q * b * np.exp(-b * np.maximum(a, 0.0)) + H + 0.0 * a)


def table(strains, stresses, extrapolation="linear"):
    """Piecewise-linear flow curve through the points ``(ε̄ᵖ_k, σ_k)``.

    The points of a tensile test's true stress against true plastic strain:
    ``strains`` start at 0 (``stresses[0]`` is the initial yield stress) and
    increase; ``stresses`` are positive and do not decrease (a softening
    curve makes the return map and the boundary value problem ill-posed).
    Between the points the stress is interpolated linearly; beyond the last
    point it continues along the last segment (``extrapolation="linear"``)
    or stays at the last stress (``"constant"``).  The slope at a point is
    that of the segment that starts there.
    """
    e = np.asarray(strains, dtype=float)
    s = np.asarray(stresses, dtype=float)
    where = "flow curve table"
    if e.ndim != 1 or e.shape != s.shape or len(e) < 2:
        raise ValueError(f"{where}: needs at least two (strain, stress) points with as "
                         f"many strains as stresses, got {e.shape} and {s.shape}")
    if not (np.all(np.isfinite(e)) and np.all(np.isfinite(s))):
        raise ValueError(f"{where}: the values must be finite")
    if e[0] != 0.0:
        raise ValueError(f"{where}: the first plastic strain must be 0 (the initial yield "
                         f"stress), not {e[0]:g}")
    steps = np.diff(e)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise ValueError(f"{where}: plastic strains must increase; point {k + 1} "
                         f"({e[k]:g}) does not exceed point {k} ({e[k - 1]:g})")
    if s[0] <= 0:
        raise ValueError(f"{where}: the initial yield stress must be positive, not {s[0]:g}")
    slopes = np.diff(s) / steps
    if np.any(slopes < 0):
        k = int(np.flatnonzero(slopes < 0)[0]) + 1
        raise ValueError(f"{where}: the stress falls from point {k} ({s[k - 1]:g}) to "
                         f"point {k + 1} ({s[k]:g}); softening is not supported")
    if extrapolation not in ("linear", "constant"):
        raise ValueError(f"{where}: extrapolation must be 'linear' or 'constant', not "
                         f"{extrapolation!r}")
    last = slopes[-1] if extrapolation == "linear" else 0.0
    segment_slopes = np.append(slopes, last)

    def segment(a):
        return np.clip(np.searchsorted(e, a, side="right") - 1, 0, len(e) - 1)

    def stress(a):
        a = np.maximum(np.asarray(a, dtype=float), 0.0)
        k = segment(a)
        return s[k] + segment_slopes[k] * (a - e[k])

    def slope(a):
        return segment_slopes[segment(np.maximum(np.asarray(a, dtype=float), 0.0))]

    return Hardening("table", stress, slope)


@dataclass
class MaterialState:
    """Internal variables at the quadrature points: ``C_p⁻¹`` (n, 3, 3), ``ε̄ᵖ`` (n,)."""

    Cp_inv: np.ndarray
    alpha: np.ndarray

    @classmethod
    def virgin(cls, n):
        return cls(np.broadcast_to(I3, (n, 3, 3)).copy(), np.zeros(n))

    def copy(self):
        return MaterialState(self.Cp_inv.copy(), self.alpha.copy())


@dataclass
class ReturnPoint:
    """What the consistent tangent needs of one stress update (n points):
    ``F⁻¹``, ``P``, the eigenvalues ``lam`` and eigenvectors ``vec`` of the
    trial ``b_e``, the trial log strains, ``Δγ``, the trial Mises stress and
    the hardening slope."""

    Finv: np.ndarray
    P: np.ndarray
    lam: np.ndarray
    vec: np.ndarray
    eps_trial: np.ndarray
    dgamma: np.ndarray
    q_trial: np.ndarray
    H: np.ndarray
    tau_p: np.ndarray


def _spectral(b):
    """Eigenvalues (n, 3) and eigenvectors (n, 3, 3) (columns) of symmetric ``b``.

    If no ``b`` couples the third axis with the others (plane strain and
    axisymmetric models: ``b_13 = b_23 = 0``), the in-plane 2 x 2 blocks are
    diagonalized in closed form, by the rotation of angle
    ``½ atan2(2 b_12, b_11 - b_22)`` (eigenvalues ``m ± r``, mean ``m`` and
    radius ``r`` of Mohr's circle), and ``b_33`` is the third eigenvalue;
    otherwise in closed form too (:func:`~skfem_rkpm.mechanics.eigen3.symmetric_eigen`,
    the same decomposition as LAPACK's ``eigh`` to round-off, 3 times faster
    on the points of a 3D model).  The order of the eigenvalues is not
    sorted: nothing downstream depends on it.
    """
    if np.any(b[:, :2, 2]) or np.any(b[:, 2, :2]):
        return symmetric_eigen(b)
    half_difference = 0.5 * (b[:, 0, 0] - b[:, 1, 1])
    angle = 0.5 * np.arctan2(b[:, 0, 1], half_difference)
    c, s = np.cos(angle), np.sin(angle)
    mean = 0.5 * (b[:, 0, 0] + b[:, 1, 1])
    radius = np.hypot(half_difference, b[:, 0, 1])
    lam = np.stack([mean + radius, mean - radius, b[:, 2, 2]], axis=1)
    vec = np.zeros_like(b)
    vec[:, 0, 0] = vec[:, 1, 1] = c
    vec[:, 1, 0], vec[:, 0, 1] = s, -s
    vec[:, 2, 2] = 1.0
    return lam, vec


#: flat places in the 9 x 9 principal matrix (rows and columns (A, B) as 3 A + B)
#: of the normal block (A A), (C C), the shear pairs (a b), (b a) and the
#: diagonal (A A), (A A)
_NORMAL = (4 * 9 * np.arange(3)[:, None] + 4 * np.arange(3)[None, :]).ravel()
_AB, _BA = 3 * _PAIR_A + _PAIR_B, 3 * _PAIR_B + _PAIR_A
_DIAGONAL = 40 * np.arange(3)


def _principal_matrix(D, g, tau_p):
    """``Ŝ - T`` (n, 9, 9) of :meth:`J2Material._tangent`: ``D_AC`` at
    ``(A A), (C C)``; for each shear pair ``a < b``, ``g_ab`` in the columns
    ``(a b)`` and ``g_ba`` in the columns ``(b a)`` of the rows ``(a b)``
    and ``(b a)`` (the blocks ``(Z_ab + Z_ba)(g_ab Z_ab + g_ba Z_ba)ᵀ``);
    minus ``τ_A`` at ``(A B), (B A)``."""
    n = D.shape[0]
    S = np.zeros((n, 81))
    S[:, _NORMAL] = D.reshape(n, 9)
    g_ab, g_ba = g[:, _PAIR_A, _PAIR_B], g[:, _PAIR_B, _PAIR_A]
    S[:, 9 * _AB + _AB] = g_ab
    S[:, 9 * _BA + _AB] = g_ab - tau_p[:, _PAIR_B]
    S[:, 9 * _AB + _BA] = g_ba - tau_p[:, _PAIR_A]
    S[:, 9 * _BA + _BA] = g_ba
    S[:, _DIAGONAL] -= tau_p
    return S.reshape(n, 9, 9)


def _log_divided_differences(lam):
    """``θ_AB = (ln λ_A - ln λ_B)/(λ_A - λ_B)``, ``θ_AA = 1/λ_A`` (n, 3, 3).

    The eigen-components of ``L = ∂ ln(b)/∂b``: for symmetric
    ``b = Σ λ_A n_A ⊗ n_A``, ``L : X = Σ_AB θ_AB (n_Aᵀ X n_B) n_A ⊗ n_B``;
    stable as eigenvalues meet, and symmetrized so that ``θ_AB = θ_BA`` to
    the last bit.
    """
    la, lb = lam[:, :, None], lam[:, None, :]
    x = (la - lb) / lb
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.where(np.abs(x) > 1e-12, np.log1p(x) / (x * lb), 1.0 / lb)
    return 0.5 * (theta + theta.transpose(0, 2, 1))


class J2Material:
    """Isotropic elasticity with von Mises plasticity at finite strain.

    Parameters
    ----------
    E, nu : float
        Young's modulus and Poisson's ratio (``-1 < ν < 0.5``).
    hardening : Hardening, optional
        Yield law; ``None`` for a purely (hyper)elastic material.
    """

    def __init__(self, E, nu, hardening=None):
        try:
            E = _number(E, "E")
        except ValueError:
            raise ValueError(f"Young's modulus E must be positive and finite, not {E!r}") \
                from None
        try:
            nu = _number(nu, "nu", low=-1.0)
        except ValueError:
            nu = np.nan if isinstance(nu, (int, float)) else nu
        if not (isinstance(nu, float) and nu < 0.5):
            raise ValueError(f"Poisson's ratio must lie in (-1, 0.5), not {nu!r}")
        if hardening is not None:
            if not isinstance(hardening, Hardening):
                raise ValueError("hardening must be a Hardening law (perfect, linear, "
                                 f"swift) or None, not {hardening!r}")
            sigma0 = np.asarray(hardening.stress(0.0), dtype=float)
            if not np.all((sigma0 > 0) & np.isfinite(sigma0)):
                raise ValueError(f"the initial yield stress must be positive and finite, "
                                 f"not {sigma0} ({hardening.name} hardening)")
        self.E, self.nu, self.hardening = E, nu, hardening
        self.G = E / (2.0 * (1.0 + nu))
        self.K = E / (3.0 * (1.0 - 2.0 * nu))

    def __repr__(self):
        law = "elastic" if self.hardening is None else self.hardening.name
        return f"J2Material(E={self.E}, nu={self.nu}, {law})"

    # -- small-strain return map in principal space ---------------------------
    def return_map(self, eps_trial, alpha_n, tol=1e-12, maxiter=50):
        """Radial return of the principal elastic log strains.

        Parameters
        ----------
        eps_trial : ndarray, shape (n, 3)
            Trial principal elastic logarithmic strains.
        alpha_n : ndarray, shape (n,)
            Accumulated plastic strain at the start of the step.

        Returns
        -------
        tau : ndarray, shape (n, 3)
            Principal Kirchhoff stresses.
        eps : ndarray, shape (n, 3)
            Principal elastic strains after the return.
        alpha : ndarray, shape (n,)
        dgamma, q_trial, H : ndarray, shape (n,)
            Plastic multiplier, trial von Mises stress and hardening slope
            (for the consistent tangent); ``dgamma == 0`` where elastic.
        """
        G, K = self.G, self.K
        vol = eps_trial.sum(axis=1)
        dev = eps_trial - vol[:, None] / 3.0
        s_trial = 2.0 * G * dev
        q_trial = np.sqrt(1.5 * np.sum(s_trial**2, axis=1))
        dgamma = np.zeros_like(alpha_n)
        H = np.zeros_like(alpha_n)
        if self.hardening is not None:
            sy, _ = self.hardening(alpha_n)
            plastic = q_trial - sy > tol * sy
            if np.any(plastic):
                try:
                    dgamma[plastic], H[plastic] = self._consistency(
                        q_trial[plastic], alpha_n[plastic], tol, maxiter)
                except ReturnMapError as err:
                    raise ReturnMapError(str(err), np.flatnonzero(plastic)[err.points])
        with np.errstate(invalid="ignore", divide="ignore"):
            factor = np.where(dgamma > 0, 1.0 - 3.0 * G * dgamma / q_trial, 1.0)
        eps = vol[:, None] / 3.0 + factor[:, None] * dev
        tau = K * vol[:, None] + factor[:, None] * s_trial
        return tau, eps, alpha_n + dgamma, dgamma, q_trial, H

    def _consistency(self, q_trial, alpha_n, tol, maxiter):
        """Solve ``q_trial - 3G Δγ - σ_y(ε̄ᵖ_n + Δγ) = 0`` by Newton's method.

        The residual falls strictly in ``Δγ`` (non-negative hardening
        slope), is positive at 0 and negative at ``q_trial / 3G``; Newton
        iterates that leave the bracket kept around the root are replaced
        by bisection, so that kinks of a tabulated flow curve cannot make
        Newton cycle.
        """
        G = self.G
        dgamma = np.zeros_like(q_trial)
        lo, hi = np.zeros_like(q_trial), q_trial / (3.0 * G)
        for _ in range(maxiter):
            sy, H = self.hardening(alpha_n + dgamma)
            f = q_trial - 3.0 * G * dgamma - sy
            lo = np.where(f > 0, dgamma, lo)
            hi = np.where(f < 0, dgamma, hi)
            step = dgamma + f / (3.0 * G + H)
            # round-off in f is relative to the trial stress
            converged = np.abs(f) <= tol * q_trial
            inside = (step >= lo) & (step <= hi)
            dgamma = np.where(inside | converged, step, 0.5 * (lo + hi))
            if np.all(converged):
                break
        else:
            bad = np.flatnonzero(~(np.abs(f) <= tol * q_trial))
            raise ReturnMapError("the plastic return map did not converge (largest yield "
                                 f"residual {np.abs(f[bad]).max():.3e})", bad)
        _, H = self.hardening(alpha_n + dgamma)
        return dgamma, H

    def _principal_tangent(self, lam, dev_dir, dgamma, q_trial, H):
        """The consistent tangent ``½ D : L : B`` in the principal frame of ``b``.

        In the eigenbasis ``n_A`` of ``b`` (eigenvalues ``λ_A``) a change
        ``X = dF F⁻¹`` gives ``db = X b + b Xᵀ`` and the Kirchhoff stress
        changes by

            dτ_AA = Σ_C D_AC X_CC,
            dτ_AB = G θ₁ θ_AB (λ_B X_AB + λ_A X_BA)     (A ≠ B),

        with the principal block ``D_AC = K + 2G θ₁ (δ_AC - 1/3) - 2G θ̄ ν_A ν_C``
        of the small-strain consistent tangent (Simo & Hughes Box 3.2;
        ``θ₁ = 1``, ``θ̄ = 0`` where elastic), ``ν`` the principal unit
        deviatoric direction and ``θ_AB`` the eigen-components of ``L``
        (:func:`_log_divided_differences`).

        Returns ``D`` (n, 3, 3) and the shear factors
        ``g_AB = G θ₁ θ_AB λ_B`` (n, 3, 3), zero on the diagonal.
        """
        G, K = self.G, self.K
        theta1 = np.ones_like(dgamma)
        theta_bar = np.zeros_like(dgamma)
        plastic = dgamma > 0
        if np.any(plastic):
            theta1[plastic] = 1.0 - 3.0 * G * dgamma[plastic] / q_trial[plastic]
            theta_bar[plastic] = 3.0 * G / (3.0 * G + H[plastic]) - (1.0 - theta1[plastic])
        D = ((K - 2.0 * G / 3.0 * theta1)[:, None, None]
             + (2.0 * G * theta1)[:, None, None] * I3
             - (2.0 * G * theta_bar)[:, None, None] * dev_dir[:, :, None] * dev_dir[:, None, :])
        g = (G * theta1)[:, None, None] * _log_divided_differences(lam) * lam[:, None, :]
        g[:, [0, 1, 2], [0, 1, 2]] = 0.0
        return D, g

    def _tangent(self, vec, Finv, tau_p, D, g, entries):
        """``A_iJkL = ∂P_iJ/∂F_kL`` at the ``entries`` (i, J), shape (n, m, m).

        ``A = ½ (D : L : B)_ijkl F⁻¹_Jj F⁻¹_Ll - τ_il F⁻¹_Jk F⁻¹_Ll`` evaluated
        in the principal frame: with ``Q`` the eigenvectors (columns) and
        ``W = F⁻¹ Q``, ``Z_(iJ),(AB) = Q_iA W_JB`` maps principal components
        to ``(i, J)`` and ``A = Z (Ŝ - T) Zᵀ``, with ``Ŝ`` the principal
        tangent of :meth:`_principal_tangent` and ``T`` the geometric term:
        ``P_iL F⁻¹_Jk = Σ_AB Z_(iJ),(AB) τ_A Z_(kL),(BA)`` since
        ``P = Q τ_p Wᵀ`` and ``F⁻¹ = W Qᵀ`` (``Q`` orthonormal), so
        ``T_(AB),(BA) = τ_A``.  ``Ŝ - T`` has 27 of its 81 entries nonzero
        (:func:`_principal_matrix`); two batched 9 x 9 products per point
        replace the broadcasts of the outer products (measured on 1536
        points: 1.1 against 2.6 ms; the same sums to round-off).
        """
        rows = np.array([i for i, _ in entries])
        cols = np.array([J for _, J in entries])
        W = Finv @ vec
        n, m = vec.shape[0], len(entries)
        if m == 9 and np.array_equal(rows, _ALL_ROWS) and np.array_equal(cols, _ALL_COLS):
            # all nine entries, row-major (3D): Z by broadcasting, no gathers
            Z = (vec[:, :, None, :, None] * W[:, None, :, None, :]).reshape(n, 9, 9)
        else:
            Z = (vec[:, rows, :, None] * W[:, cols, None, :]).reshape(n, m, 9)
        return (Z @ _principal_matrix(D, g, tau_p)) @ Z.transpose(0, 2, 1)

    # -- finite strain ----------------------------------------------------------
    def update(self, F, state, tangent=True, entries=None):
        """Stress, new state and consistent tangent for deformation gradients ``F``.

        Parameters
        ----------
        F : ndarray, shape (n, 3, 3)
        state : MaterialState
            State at the start of the step (not modified).
        tangent : bool
            Also return ``A = ∂P/∂F``.
        entries : sequence of (i, J), optional
            Return the tangent only between these entries of ``P`` and
            ``F``, as an (n, m, m) array ``A[(i, J), (k, L)]`` (e.g. the
            four in-plane entries of plane strain); default all nine, as
            (n, 3, 3, 3, 3).

        Returns
        -------
        P : ndarray, shape (n, 3, 3)
            First Piola-Kirchhoff stress.
        tau : ndarray, shape (n, 3, 3)
            Kirchhoff stress (``σ = τ / det F``).
        new_state : MaterialState
        A : ndarray, shape (n, 3, 3, 3, 3) or (n, m, m), or None
        """
        P, tau, new_state, point = self.stress(F, state)
        return P, tau, new_state, self.tangent(point, entries) if tangent else None

    def stress(self, F, state):
        """Stress and new state for ``F``, and what :meth:`tangent` needs.

        Returns ``P``, ``tau``, ``new_state`` as :meth:`update` does and a
        :class:`ReturnPoint` from which :meth:`tangent` forms ``∂P/∂F``
        later, only if it is asked for (a Newton line search rejects some
        states, and the converged state needs no tangent).
        """
        Finv, _ = inverse_and_determinant(F)
        b = F @ state.Cp_inv @ F.transpose(0, 2, 1)
        b = 0.5 * (b + b.transpose(0, 2, 1))
        lam, vec = _spectral(b)
        eps_trial = 0.5 * np.log(lam)
        tau_p, eps, alpha, dgamma, q_trial, H = self.return_map(eps_trial, state.alpha)

        def tensor(principal):
            return (vec * principal[:, None, :]) @ vec.transpose(0, 2, 1)

        tau = tensor(tau_p)
        b_new = tensor(np.exp(2.0 * eps))
        Cp_inv = Finv @ b_new @ Finv.transpose(0, 2, 1)
        new_state = MaterialState(0.5 * (Cp_inv + Cp_inv.transpose(0, 2, 1)), alpha)
        P = tau @ Finv.transpose(0, 2, 1)
        return P, tau, new_state, ReturnPoint(Finv, P, lam, vec, eps_trial, dgamma,
                                              q_trial, H, tau_p)

    def tangent(self, point, entries=None):
        """Consistent tangent ``A = ∂P/∂F`` at a :class:`ReturnPoint` of
        :meth:`stress`, between ``entries`` as in :meth:`update`."""
        dev_trial = point.eps_trial - point.eps_trial.mean(axis=1, keepdims=True)
        norm = np.linalg.norm(dev_trial, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            dev_dir = np.where(norm[:, None] > 0, dev_trial / norm[:, None], 0.0)
        D, g = self._principal_tangent(point.lam, dev_dir, point.dgamma, point.q_trial,
                                       point.H)
        full = entries is None
        if full:
            entries = [(i, J) for i in range(3) for J in range(3)]
        A = self._tangent(point.vec, point.Finv, point.tau_p, D, g, entries)
        return A.reshape(-1, 3, 3, 3, 3) if full else A
