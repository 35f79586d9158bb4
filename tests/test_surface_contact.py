"""3D frictional contact with rigid tool surfaces: the vector Coulomb return
map, the consistent tangent against finite differences in open, stick and
slip states, and a block dragged over a rough plane in an arbitrary
tangential direction (|t| = μ p in slip, no slip in stick)."""

from dataclasses import dataclass

import numpy as np
import pytest
from skfem import Basis, ElementHex1, ElementVector, MeshHex

from skfem_rkpm import RKBasis
from skfem_rkpm.mechanics.friction import coulomb_vector
from skfem_rkpm.mechanics.materials import J2Material, linear
from skfem_rkpm.mechanics.problem import SolidProblem
from skfem_rkpm.mechanics.surface_contact import SurfaceContact
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from skfem_rkpm.verification.exact import uniaxial_compression

E, NU = 200e3, 0.3
LAW = linear(300.0, 2000.0)


@dataclass
class _Projection:
    point: np.ndarray
    normal: np.ndarray
    gap: np.ndarray
    curvature: np.ndarray
    feature: np.ndarray


class _Ball:
    """An analytic sphere tool (body outside) translating with ``motion``:
    the test's own geometry, independent of :mod:`.surfaces`."""

    name = "ball"

    def __init__(self, center, radius, motion):
        self.center, self.radius = np.asarray(center, float), float(radius)
        self.motion = np.asarray(motion, float)

    def placement(self, t):
        return np.eye(3), t * self.motion

    def translation(self, t):
        return t * self.motion

    def to_body(self, x, t):
        return x - (t * self.motion)[:, None]

    def project(self, x, t=0.0):
        v = self.to_body(x, t) - self.center[:, None]
        rho = np.linalg.norm(v, axis=0)
        n = v / rho
        C = (np.eye(3)[None] - np.einsum("in,jn->nij", n, n)) / rho[:, None, None]
        point = self.center[:, None] + self.radius * n + (t * self.motion)[:, None]
        return _Projection(point, n, rho - self.radius, C, np.zeros(x.shape[1], int))


class _Floor:
    """The plane ``z = level`` translating with ``motion``: body above it
    (``up``) or below it."""

    def __init__(self, level=0.0, motion=(0.0, 0.0, 0.0), up=True, name="floor"):
        self.level, self.motion = level, motion
        self.sign, self.name = (1.0 if up else -1.0), name

    def _shift(self, t):
        return np.asarray(self.motion(t) if callable(self.motion)
                          else t * np.asarray(self.motion, float), float)

    def placement(self, t):
        return np.eye(3), self._shift(t)

    def translation(self, t):
        return self._shift(t)

    def to_body(self, x, t):
        return x - self._shift(t)[:, None]

    def project(self, x, t=0.0):
        local = self.to_body(x, t)
        n = np.zeros_like(x)
        n[2] = self.sign
        gap = self.sign * (local[2] - self.level)
        return _Projection(x - gap * n, n, gap, np.zeros((x.shape[1], 3, 3)),
                           np.zeros(x.shape[1], int))


def cube(n=2, size=1.0):
    t = np.linspace(0.0, size, n + 1)
    return MeshHex.init_tensor(t, t, t).with_boundaries({
        "bottom": lambda x: x[2] < 1e-9, "top": lambda x: x[2] > size - 1e-9,
        "xmin": lambda x: x[0] < 1e-9, "ymin": lambda x: x[1] < 1e-9})


def problem_on(kind, mesh):
    basis = (RKBasis(mesh, vector=True, support=2.0, intorder=2) if kind == "rk"
             else Basis(mesh, ElementVector(ElementHex1()), intorder=2))
    return SolidProblem(basis, J2Material(E, NU, LAW), "3d")


def test_vector_return_map_keeps_the_direction_and_caps_the_size():
    """Eq. (4.6) in a tangent plane: stick returns the trial; slip scales
    it to μ t_n along the trial direction; μ = 0 and ∞ are the limits."""
    pressure = np.array([1.0, 1.0, 0.0])
    trial = np.array([[0.1, 0.2, 0.0], [3.0, -4.0, 0.0], [0.0, 0.0, 0.0]])
    shear, slip = coulomb_vector(pressure, trial, 0.5)
    np.testing.assert_array_equal(slip, [False, True, False])
    np.testing.assert_allclose(shear[0], trial[0])
    np.testing.assert_allclose(shear[1], 0.5 * np.array([0.6, -0.8, 0.0]), rtol=1e-15)
    assert np.all(coulomb_vector(pressure, trial, 0.0)[0] == 0)
    np.testing.assert_array_equal(coulomb_vector(pressure, trial, np.inf)[0], trial)


def assert_tangent_matches_differences(contact, d, t, K, h=1e-7):
    """``K`` equals the central differences of the contact force, column by
    column, to 1e-7 of its largest entry (h = 1e-7 against displacements
    of 1e-2: truncation ~h², round-off ~1e-16/h of the force)."""
    fd = np.column_stack([(contact.evaluate(d + h * e, t)[0]
                           - contact.evaluate(d - h * e, t)[0]) / (2 * h)
                          for e in np.eye(len(d))])
    K = K.toarray()
    assert np.abs(K - fd).max() < 1e-7 * np.abs(K).max()


TOOLS = {
    "ball": lambda: _Ball((0.45, 0.55, 1.8), 0.95, motion=(0.05, -0.02, -0.05)),
    "floor": lambda: _Floor(0.02, motion=(0.1, 0.05, 0.03)),
}
SLAVES = {"ball": "top", "floor": "bottom"}


@pytest.mark.parametrize("tool", list(TOOLS))
@pytest.mark.parametrize("friction", [0.0, 0.3, "stick"])
@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
@pytest.mark.parametrize("enforcement", ["penalty", "augmented"])
def test_surface_contact_tangent_is_the_derivative_of_the_force(tool, friction, kind,
                                                               collocation, enforcement):
    """The 3D form of Eq. (4.28)-(4.29): normal, stick and slip terms, the
    curvature of a sphere, touching nodes, mapped with Λ for RK bases."""
    problem = problem_on(kind, cube())
    contact = SurfaceContact(problem, TOOLS[tool](), SLAVES[tool], friction, collocation,
                             penalty=1e5, tangential_penalty=2e4, enforcement=enforcement)
    rng = np.random.default_rng(4)
    d0 = 0.01 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d = d0 + 0.01 * rng.normal(size=problem.N)
    _, K = contact.evaluate(d, 0.6)
    state = contact.trial
    assert state.active.any()
    if tool == "ball" and collocation == "nodal":
        assert (~state.active).any()
    if friction == 0.3 and enforcement == "penalty":  # both branches of the return map
        assert state.slip.any() and (state.active & ~state.slip).any()
    assert_tangent_matches_differences(contact, d, 0.6, K)


# ---------------------------------------------------------------------------
# homogeneous compression and friction on a block
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("fem", "quadrature"),
                                               ("rk", "quadrature")])
def test_block_under_a_frictionless_platen_is_exact(kind, collocation):
    """1/8 of a cube between frictionless platens (symmetry on x = 0, y = 0,
    z = 0), compressed 30 % by a descending plane: every step on the
    homogeneous J2 closed form (uniaxial stress), with the compression
    taken as the platen travel minus its penetration; stresses and
    lateral displacements homogeneous to 1e-8."""
    problem = problem_on(kind, cube())
    top = SurfaceContact(problem, _Floor(1.0, (0, 0, -0.3), up=False, name="top"), "top",
                         collocation=collocation)
    bottom = SurfaceContact(problem, _Floor(0.0, name="bottom"), "bottom",
                            collocation=collocation)
    # the symmetry planes carry no traction (σ_xx = σ_yy = 0); a nodal
    # constraint at z = 0 would have to carry σ_zz, which RK bases cannot
    # represent exactly through nodal values, so the bottom is a platen too
    fixed = [Prescribed("xmin", 0), Prescribed("ymin", 1)]
    changes = []
    result = newton_steps(problem, fixed, steps=6, tol=1e-10, contributions=[top, bottom],
                          on_step=lambda r, d, ev: changes.append(
                              0.3 * r.t - top.penetration() - bottom.penetration()))
    assert result.completed, result.message
    for record, delta in zip(result.history, changes):
        exact = uniaxial_compression(delta, E, NU, LAW)
        assert record.reactions["top"][2] == pytest.approx(exact.nominal, rel=1e-8)
        assert np.abs(record.reactions["top"][:2]).max() < 1e-8 * abs(exact.nominal)
    exact = uniaxial_compression(changes[-1], E, NU, LAW)
    stress = problem.cauchy_stress(problem.evaluate(result.d, tangent=False))
    np.testing.assert_allclose(stress[:, 2, 2], exact.cauchy, rtol=1e-8)
    np.testing.assert_allclose(stress[:, 0, 0], 0.0, atol=1e-8 * abs(exact.cauchy))
    np.testing.assert_allclose(problem.state.alpha, exact.alpha, rtol=1e-8)
    assert top.penetration() == pytest.approx(bottom.penetration(), rel=1e-8)
    assert 0 < top.penetration() < 1e-5


def drag(kind, friction, distance, angle=np.radians(35.0), press=2e-3, steps=8, **kw):
    """A cube held at its top face (u = 0 in x, y; pressed down by ``press``
    in the first half of the load) on a floor that slides ``distance`` in
    the direction ``angle`` from x in the second half."""
    problem = problem_on(kind, cube())
    e = np.array([np.cos(angle), np.sin(angle), 0.0])
    floor = _Floor(0.0, lambda t: max(0.0, 2 * t - 1) * distance * e)
    contact = SurfaceContact(problem, floor, "bottom", friction, **kw)
    held = [Prescribed("top", 0), Prescribed("top", 1),
            Prescribed("top", 2, lambda t, x: -press * min(2 * t, 1.0) + 0 * x[0])]
    result = newton_steps(problem, held, steps=steps, tol=1e-10, contributions=[contact])
    assert result.completed, result.message
    return result, contact, e


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_block_dragged_on_a_rough_plane_slips_at_mu_p_along_the_drag(kind):
    """Every pressed node slips (drag 0.05 mm, the stick limit is ~1e-3 mm):
    its shear is μ t_n (Eq. 4.6) along the drag direction, at 35° to
    the mesh lines, so the resultant is μ times the normal force along the
    drag.  Once sliding is steady the nodes hardly move, so the slip
    direction is the drag direction up to the nodes' own creep over the
    last step relative to the floor's (measured 1.4e-6; asserted 1e-5)."""
    result, contact, e = drag(kind, 0.3, 0.05)
    state = contact.state
    pressed = state.active
    assert pressed.sum() == state.active.size and state.slip[pressed].all()
    np.testing.assert_allclose(np.linalg.norm(state.shear, axis=1),
                               0.3 * state.pressure, rtol=1e-12)
    force = result.history[-1].reactions["floor"]
    np.testing.assert_allclose(force[:2] / np.linalg.norm(force[:2]), e[:2], atol=1e-5)
    assert np.linalg.norm(force[:2]) == pytest.approx(0.3 * force[2], rel=1e-10)


@pytest.mark.parametrize("kind", ["fem", "rk"])
def test_block_dragged_below_the_friction_limit_sticks(kind):
    """A drag of 2e-5 mm after the press: the nodes that stick (all but the
    edge nodes that slipped outward while the block was pressed) follow the
    floor with the augmented Lagrangian: their displacement over the drag
    is the floor's to its tolerance, here 1e-9 h_c per step (4 drag steps:
    2e-9 mm); the nodes that slip carry |t| = μ t_n; the resultant stays
    below μ times the normal force."""
    result, contact, e = drag(kind, 0.3, 2e-5, enforcement="augmented", tolerance=1e-9)
    state = contact.state
    sticking = state.active & ~state.slip
    assert state.active.all() and sticking.sum() >= 4
    pressed_at = [r.t for r in result.history].index(0.5)
    moved = contact.points.displacements(result.d - result.solutions[pressed_at])
    drift = moved[:, sticking] - (2e-5 * e)[:, None]
    assert np.abs(drift).max() < 4 * 1e-9 * contact.points.spacing
    np.testing.assert_allclose(np.linalg.norm(state.shear[state.slip], axis=1),
                               0.3 * state.pressure[state.slip], rtol=1e-12)
    force = result.history[-1].reactions["floor"]
    assert np.linalg.norm(force[:2]) < 0.3 * force[2]
