"""Rigid-tool contact on the symmetry planes of a 3D model, and the
augmented Lagrangian's multipliers carried from step to step.

A contact node on a symmetry plane carries no shear across it (the
mirrored half pulls the other way): its slip is projected off the plane's
normal (:func:`symmetry_projection`).  Under a weak symmetry condition an
RK particle on the plane is held there only in the mean, so without the
projection its slip across the plane does not answer to its shear and the
augmented Lagrangian stalls."""

import numpy as np
import pytest

from skfem_rkpm.mechanics.surface_contact import SurfaceContact, symmetry_projection
from skfem_rkpm.solvers.newton import Prescribed, newton_steps
from test_surface_contact import (TOOLS, _Floor, assert_tangent_matches_differences, cube,
                                  problem_on)

PLANES = [("xmin", (1.0, 0.0, 0.0)), ("ymin", (0.0, 1.0, 0.0))]


def _on(mesh, boundary, nodes):
    return np.isin(nodes, np.unique(mesh.facets[:, mesh.boundaries[boundary]]))


def test_symmetry_projection_removes_the_normals_of_the_planes_through_a_node():
    """Orthogonal projections: the identity off the planes, rank 2 on one
    plane (its normal removed), rank 1 where two meet, also at an angle
    (a wedge of 60°: the line of the two planes is what is left)."""
    mesh = cube(2)
    nodes = np.arange(mesh.nvertices)
    n2 = np.array([np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0])
    Q = symmetry_projection(mesh, nodes, [("xmin", (2.0, 0.0, 0.0)), ("ymin", n2)])
    on_x, on_y = _on(mesh, "xmin", nodes), _on(mesh, "ymin", nodes)
    np.testing.assert_allclose(np.einsum("kij,kjl->kil", Q, Q), Q, atol=1e-15)
    np.testing.assert_allclose(Q, Q.transpose(0, 2, 1), atol=1e-15)
    rank = np.round(np.trace(Q, axis1=1, axis2=2)).astype(int)
    np.testing.assert_array_equal(rank, 3 - on_x.astype(int) - on_y.astype(int))
    np.testing.assert_allclose(Q[on_x] @ np.array([1.0, 0.0, 0.0]), 0.0, atol=1e-15)
    np.testing.assert_allclose(Q[on_y] @ n2, 0.0, atol=1e-15)
    both = on_x & on_y
    np.testing.assert_allclose(Q[both], np.broadcast_to(np.diag([0.0, 0.0, 1.0]),
                                                        Q[both].shape), atol=1e-15)
    np.testing.assert_array_equal(Q[~on_x & ~on_y], np.eye(3)[None].repeat(
        np.count_nonzero(~on_x & ~on_y), axis=0))


def test_symmetry_planes_are_checked():
    mesh = cube(2)
    with pytest.raises(ValueError, match="no such boundary"):
        symmetry_projection(mesh, np.arange(3), [("front", (1.0, 0.0, 0.0))])
    with pytest.raises(ValueError, match="not all zero"):
        symmetry_projection(mesh, np.arange(3), [("xmin", (0.0, 0.0, 0.0))])
    problem = problem_on("rk", mesh)
    with pytest.raises(ValueError, match="not 'gauss'"):
        SurfaceContact(problem, _Floor(0.0), "bottom", 0.3, "gauss", symmetry=PLANES)


@pytest.mark.parametrize("friction", [0.3, "stick"])
@pytest.mark.parametrize("kind, collocation", [("fem", "nodal"), ("rk", "nodal"),
                                               ("rk", "quadrature")])
@pytest.mark.parametrize("enforcement", ["penalty", "augmented"])
def test_tangent_with_symmetry_planes_is_the_derivative_of_the_force(friction, kind,
                                                                      collocation,
                                                                      enforcement):
    """The stick and slip terms with the projected slip ``Q ŝ`` against
    central differences; the nodes on the planes carry no shear along
    their normals."""
    problem = problem_on(kind, cube())
    contact = SurfaceContact(problem, TOOLS["floor"](), "bottom", friction, collocation,
                             penalty=1e5, tangential_penalty=2e4, enforcement=enforcement,
                             symmetry=PLANES)
    rng = np.random.default_rng(4)
    d0 = 0.01 * rng.normal(size=problem.N)
    contact.evaluate(d0, 0.5)
    contact.commit()
    d = d0 + 0.01 * rng.normal(size=problem.N)
    _, K = contact.evaluate(d, 0.6)
    state, nodes, mesh = contact.trial, contact.points.nodes, problem.basis.mesh
    on_x, on_y = _on(mesh, "xmin", nodes), _on(mesh, "ymin", nodes)
    assert (state.active & on_x).any() and (state.active & ~on_x & ~on_y).any()
    assert np.all(state.shear[on_x, 0] == 0) and np.all(state.shear[on_y, 1] == 0)
    assert np.abs(state.shear[state.active & ~on_x & ~on_y]).max() > 0
    assert_tangent_matches_differences(contact, d, 0.6, K)


def upset(symmetry, steps=5, max_augmentations=10, extrapolate_multipliers=True):
    """An RK cube, 1/8 of a block (weak symmetry on x = 0, y = 0, z = 0),
    upset 10 % by a rough platen (μ = 0.3, augmented Lagrangian)."""
    problem = problem_on("rk", cube(3))
    top = SurfaceContact(problem, _Floor(1.0, (0, 0, -0.1), up=False, name="top"), "top",
                         0.3, enforcement="augmented", factor=10.0,
                         symmetry=PLANES if symmetry else ())
    if not extrapolate_multipliers:
        restart = top.restart
        top.restart = lambda t=None: restart()
    weak = [Prescribed("xmin", 0, method="weak"), Prescribed("ymin", 1, method="weak"),
            Prescribed("bottom", 2, method="weak")]
    result = newton_steps(problem, weak, steps=steps, tol=1e-8, contributions=[top],
                          max_augmentations=max_augmentations)
    return problem, top, result


def test_rough_platen_on_weak_symmetry_planes_converges_without_shear_across_them():
    """With the planes the augmented Lagrangian converges in every step
    (at most 10 multiplier updates, no cut-back) and the nodes on the
    planes carry no shear across them.  Without them the first step is
    cut back (the particles on x = 0 slip across the plane at a fixed
    amount whatever their shear, which grows by ω_t ŝ per update: 67 MPa
    against a pressure of 740 MPa at the end, measured)."""
    problem, top, result = upset(True)
    assert result.completed and len(result.history) == 5
    assert all(r.cutbacks == 0 for r in result.history)
    mesh, nodes, state = problem.basis.mesh, top.points.nodes, top.state
    on_x, on_y = _on(mesh, "xmin", nodes), _on(mesh, "ymin", nodes)
    assert state.active[on_x].all()
    assert np.all(state.shear[on_x, 0] == 0) and np.all(state.shear[on_y, 1] == 0)
    assert np.abs(state.shear[on_x, 1]).max() > 0.01 * state.pressure.max()
    assert top.violation() <= 1.0
    _, _, stalled = upset(False)
    assert sum(r.cutbacks for r in stalled.history) > 0


def test_extrapolated_multipliers_start_on_the_rates_and_keep_the_answer():
    """``restart(t)`` starts the multipliers at the converged tractions
    plus ``(t - t_state)`` times their rate over the last step (pressures
    not below 0); the converged steps agree with the run whose multipliers
    start at the last tractions to the augmented Lagrangian's tolerance
    (penetration and stick slip 1e-6 h_c: measured 4e-6 of the platen
    force in the shear, 2e-7 in the normal force) while the predicted
    multipliers save updates (measured 82 against 97 iterations)."""
    _, top, result = upset(True, steps=10, max_augmentations=30)
    state = top.state
    assert state.t == 1.0 and np.abs(state.pressure_rate).max() > 0
    top.restart(1.1)
    np.testing.assert_allclose(top.multipliers[0],
                               np.maximum(state.pressure + 0.1 * state.pressure_rate, 0.0))
    np.testing.assert_allclose(top.multipliers[1], state.shear + 0.1 * state.shear_rate)
    top.restart()
    np.testing.assert_array_equal(top.multipliers[1], state.shear)
    _, _, plain = upset(True, steps=10, max_augmentations=30, extrapolate_multipliers=False)
    forces = np.array([r.reactions["top"] for r in result.history])
    reference = np.array([r.reactions["top"] for r in plain.history])
    scale = np.abs(reference[:, 2]).max()
    np.testing.assert_allclose(forces[:, :2], reference[:, :2], atol=2e-5 * scale)
    np.testing.assert_allclose(forces[:, 2], reference[:, 2], atol=1e-6 * scale)
    spent = sum(r.spent_iterations for r in result.history)
    assert spent < sum(r.spent_iterations for r in plain.history)
