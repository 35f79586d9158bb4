"""The penalty-regularized Coulomb law, Eq. (4.3)-(4.6) of Chen, Pan, Roque &
Wang (1998), and its penalties.

The contact constraint ``g_n ≥ 0`` and Coulomb's law (Eq. 4.3) are enforced
with the penalized tractions of Eq. (4.5)-(4.6):

    t_n = ω_n ⟨-g_n⟩,
    t_t = t_t,n - ω_t Δg_t            if |t_t,n - ω_t Δg_t| ≤ μ t_n   (stick)
    t_t = μ t_n sgn(t_t,n - ω_t Δg_t)  otherwise                       (slip)

where ``Δg_t`` is the tangential slip of the slave point relative to the
master surface since the last converged step (Eq. 4.11) and ``t_t,n`` the
tangential traction of that step (the return map of a penalty regularized
Coulomb law).  ``t_n`` pushes the body along ``n``; ``t_t`` acts along the
tangent ``t`` of the master surface (``n = e_3 × t``, Eq. 4.7).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_PENALTY_FACTOR", "DEFAULT_TANGENTIAL_FACTOR", "DEFAULT_AUGMENTED_TOLERANCE",
           "default_penalty", "STICK_FRICTION", "friction_coefficient", "coulomb",
           "coulomb_vector", "ContactState"]

#: ω_n = DEFAULT_PENALTY_FACTOR · E / h_c per unit area of the contact
#: boundary (h_c the particle spacing along it).  A contact pressure p then
#: penetrates g = p h_c / (1000 E): for metals (p ≲ 3 σ_y ≈ 1e-2 E) below
#: 1e-5 h_c.  Between 1e2 and 1e4 the Newton iteration counts do not change
#: (measured, docs/contact.md).
DEFAULT_PENALTY_FACTOR = 1e3

#: ω_t = DEFAULT_TANGENTIAL_FACTOR · E / h_c.  The elastic slip of a
#: sticking point, t_t / ω_t ≤ μ (t_n / E) h_c, is then below 1 % of the
#: spacing for metals.  A stiffer ω_t turns the stick/slip law into a near
#: step function of the displacement and Newton cycles between stick and
#: reversed slip (measured: ω_t = ω_n needs cut-backs, docs/contact.md).
DEFAULT_TANGENTIAL_FACTOR = 1.0

#: the augmented Lagrangian stops when pressed nodes penetrate, and sticking
#: nodes slip, less than this fraction of the particle spacing h_c
DEFAULT_AUGMENTED_TOLERANCE = 1e-6


def default_penalty(E, spacing, factor=DEFAULT_PENALTY_FACTOR):
    """Penalty ``ω = factor · E / h_c`` per unit boundary area (Eq. 4.5).

    Independent of the mesh in the sense that the penetration under a given
    pressure, ``g = p / ω``, is a fixed fraction ``p / (factor E)`` of the
    particle spacing ``h_c``.
    """
    if not (np.isfinite(E) and E > 0):
        raise ValueError(f"Young's modulus must be positive, not {E!r}")
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"penalty factor must be positive, not {factor!r}")
    return factor * E / spacing


#: the Coulomb coefficient that models ``friction = "stick"``
STICK_FRICTION = 10.0


def friction_coefficient(friction, exact_stick=False):
    """``μ`` of ``friction``: a number ``≥ 0``, or ``"stick"``.

    With ``exact_stick`` (the augmented Lagrangian) ``"stick"`` is ``μ = ∞``.
    With the penalty law it is ``μ = STICK_FRICTION``, for this reason:

    Sticking means no slip wherever the tool presses, the limit ``μ → ∞``
    of Eq. (4.6).  The limit itself is discontinuous where a node leaves
    the tool: its shear drops from the sticking value to zero while its
    pressure is already zero.  At a corner that folds onto the tool the
    penalty problem then has no solution (the node is pushed back in by
    the shear it loses when it separates) and Newton's method cycles
    between the two states.  ``"stick"`` is therefore the Coulomb law with
    ``μ = STICK_FRICTION`` (10): the shear a node can hold vanishes with
    its pressure.  Measured on the paper's stick ring (100 steps to 50 %
    height reduction): 99 % of the pressed nodes carry ``|t_t| ≤ 1.1 t_n``;
    at most one node slips in any step, at the edge of the contact, with a
    pressure below 0.6 % (RKPM) / 4.8 % (FEM Q1) of the largest; the inner
    radius at mid-height differs by 3e-5 (relative) between μ = 10, 100 and
    1000, and both runs reach 50 % (the limit law stops them near 49 %).
    """
    if isinstance(friction, str):
        if friction == "stick":
            return np.inf if exact_stick else STICK_FRICTION
        raise ValueError(f'friction must be a number >= 0 or "stick", not {friction!r}')
    mu = float(friction)
    if not (np.isfinite(mu) and mu >= 0):
        raise ValueError(f'friction must be a number >= 0 or "stick", not {friction!r}')
    return mu


def coulomb(pressure, trial, mu):
    """Return map of the penalized Coulomb law (Eq. 4.6).

    Parameters
    ----------
    pressure : ndarray
        Normal traction ``t_n ≥ 0``.
    trial : ndarray
        Trial tangential traction ``t_t,n - ω_t Δg_t``.
    mu : float
        Friction coefficient (0: frictionless, ``inf``: stick).

    Returns
    -------
    shear : ndarray
        Tangential traction: the trial value in stick, ``μ t_n sgn(trial)``
        in slip.
    slip : ndarray of bool
    """
    if mu == 0.0:
        return np.zeros_like(trial), pressure > 0
    if mu == np.inf:
        return trial.copy(), np.zeros(trial.shape, bool)
    slip = np.abs(trial) > mu * pressure
    return np.where(slip, mu * pressure * np.sign(trial), trial), slip


def coulomb_vector(pressure, trial, mu):
    """Return map of the penalized Coulomb law (Eq. 4.6) in a tangent plane:
    the slip direction is a vector.

    Parameters
    ----------
    pressure : ndarray (m,)
        Normal traction ``t_n ≥ 0``.
    trial : ndarray (m, d)
        Trial tangential traction ``t_t,n - ω_t Δg_t`` (vectors).
    mu : float
        Friction coefficient (0: frictionless, ``inf``: stick).

    Returns
    -------
    shear : ndarray (m, d)
        The trial traction in stick, ``μ t_n τ`` with ``τ = trial / |trial|``
        in slip.
    slip : ndarray (m,) of bool
    """
    if mu == 0.0:
        return np.zeros_like(trial), pressure > 0
    if mu == np.inf:
        return trial.copy(), np.zeros(len(trial), bool)
    size = np.linalg.norm(trial, axis=1)
    slip = size > mu * pressure
    scale = np.where(slip, mu * pressure / np.where(slip, size, 1.0), 1.0)
    return scale[:, None] * trial, slip


@dataclass
class ContactState:
    """Contact data at one evaluation.

    Per slave point: ``x`` (2, n) current positions, ``gap`` (n,) normal
    gaps ``g_n``, ``normal``/``tangent`` (2, n) master frame at the closest
    points, ``relative`` (2, n) positions relative to the tool,
    ``x - x_tool(t)`` (for the slip of Eq. 4.11).  Per contact node:
    ``pressure`` ``t_n``, ``shear`` ``t_t`` (along the tangent), ``slip``
    and ``active`` (bool), and ``node_gap`` (the nodal gap, or the
    hat-weighted average of the point gaps).  ``force`` (2,) is the force of
    the master surface on the body.  A converged state also keeps its load
    factor ``t`` and the rates ``pressure_rate``, ``shear_rate`` of the
    nodal tractions over the step that reached it (zero where a node was
    not in contact at both ends): the augmented Lagrangian starts the next
    step's multipliers from them (:meth:`RigidContact.restart`).
    """

    x: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    relative: np.ndarray
    node_gap: np.ndarray
    pressure: np.ndarray
    shear: np.ndarray
    slip: np.ndarray
    active: np.ndarray
    force: np.ndarray
    t: float = 0.0
    pressure_rate: np.ndarray = None
    shear_rate: np.ndarray = None

    def __post_init__(self):
        # plain arrays, also for checkpoints
        self.t = np.float64(self.t)
        if self.pressure_rate is None:
            self.pressure_rate = np.zeros(np.shape(self.pressure))
        if self.shear_rate is None:
            self.shear_rate = np.zeros(np.shape(self.shear))

    @property
    def penetration(self):
        """Largest penetration ``max(-g_n, 0)`` over the slave points."""
        return float(max(0.0, -self.gap.min(initial=0.0)))


def _positive(value, what):
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{what} must be positive, not {value!r}")
    return value


