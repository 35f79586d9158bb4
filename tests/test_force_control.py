"""Force-driven tools: a platen that pushes with a prescribed force.

A block on a frictionless base (plane strain, symmetric about its left
side) is compressed by a platen on its top whose push follows a force
history; the platen's travel is the extra unknown.  With a uniform contact
pressure the block is in homogeneous uniaxial compression, whose closed
form (nominal stress -F/w) is checked, and the platen travels by the
shortening plus the penalty penetration p/ω_n.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.runner import run
from skfem_rkpm.runs.scene import SceneError, parse_scene

E, NU = 1000.0, 0.3
LAM, G = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))

SCENE = """
[geometry]
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [3, 3]

[material]
E = 1000.0
nu = 0.3

[discretization]
element = "quad1"

[tools.holder]
kind = "platen"
point = [0.0, 1.0]
normal = [0.0, -1.0]
force = {force}
slaves = ["top"]
penalty = 1e5

[boundary.left]
fix = ["x"]

[boundary.bottom]
fix = ["y"]

[steps]
count = 4
tolerance = 1e-10

[output]
points = {{ corner = [1.0, 1.0] }}
"""


def plane_strain_stretch(p):
    """Height stretch λ_y of a plane strain block under the nominal axial
    stress -p, free laterally: log strains e_x = -λ e_y / (λ + 2G) (zero
    lateral stress), τ_yy = λ (e_x + e_y) + 2G e_y, P_yy = τ_yy / λ_y."""
    def nominal(ey):
        ex = -LAM * ey / (LAM + 2 * G)
        return (LAM * (ex + ey) + 2 * G * ey) / np.exp(ey) + p

    return np.exp(brentq(nominal, -0.5, 0.0, xtol=1e-15))


@pytest.mark.parametrize("force, level", [
    ("30.0", lambda t: t),
    ("[[0.0, 0.0], [0.5, 30.0], [1.0, 30.0]]", lambda t: min(2 * t, 1.0)),
])
def test_platen_driven_by_force_compresses_the_block_exactly(force, level):
    sim = build(parse_scene(SCENE.format(force=force)), "fem")
    result = run(sim, progress=False)
    assert result.completed, result.message
    omega = sim.tools[0].contact.omega_n
    for record, gauges in zip(result.history, result.gauges):
        F = 30.0 * level(record.t)
        # the push is the prescribed force (the scalar solve, 1e-12)
        assert -record.reactions["holder"][1] == pytest.approx(F, rel=1e-10)
        lam = plane_strain_stretch(F)  # width 1: p = F
        assert gauges["corner y"] == pytest.approx(lam, rel=1e-9)
        # travel = shortening + penetration of the uniform pressure p / ω_n
        assert gauges["holder travel"] == pytest.approx(1 - lam + F / omega, rel=1e-8)
    assert plane_strain_stretch(30.0) < 0.975  # a 2.5 % shortening, not a trivial one


def test_newton_converges_quadratically_with_the_travel_eliminated():
    """The Schur complement is the exact tangent: the last step's residuals
    4.0e-3, 7.9e-7, 3.3e-14 (measured), each about the square of the last
    times a constant of order 0.05."""
    sim = build(parse_scene(SCENE.format(force="30.0")), "fem")
    result = run(sim, progress=False)
    last = result.history[-1].residuals
    assert len(last) == 3 and last[2] < last[1] ** 1.8
    assert all(r.iterations <= 3 for r in result.history)


def test_force_driven_rkpm_block_holds_the_force():
    """RKPM (nodal contact collocation): the push equals the force; the
    height is the closed form to the nodal-collocation error of RK
    (nodal forces of a uniform pressure are not the consistent ones;
    measured 6.6e-5)."""
    sim = build(parse_scene(SCENE.format(force="30.0")), "rkpm")
    result = run(sim, progress=False)
    assert result.completed, result.message
    record, gauges = result.history[-1], result.gauges[-1]
    assert -record.reactions["holder"][1] == pytest.approx(30.0, rel=1e-10)
    assert gauges["corner y"] == pytest.approx(plane_strain_stretch(30.0), rel=2e-4)


def test_force_driven_arc_needs_a_direction():
    scene = SCENE.format(force="30.0").replace(
        'kind = "platen"\npoint = [0.0, 1.0]\nnormal = [0.0, -1.0]',
        'kind = "arc"\ncenter = [0.5, 2.0]\nradius = 1.0\nangles = [200.0, 340.0]')
    with pytest.raises(SceneError, match="force-driven arc needs 'direction'"):
        parse_scene(scene)


def test_force_driven_tool_with_augmented_contact_travels_by_the_shortening():
    """With the augmented Lagrangian contact (penetration driven to
    1e-6 h_c) the travel is the shortening itself: measured 4e-12 apart."""
    scene = SCENE.format(force="30.0").replace("penalty = 1e5", 'enforcement = "augmented"')
    result = run(build(parse_scene(scene), "fem"), progress=False)
    assert result.completed, result.message
    assert -result.history[-1].reactions["holder"][1] == pytest.approx(30.0, rel=1e-10)
    lam = plane_strain_stretch(30.0)
    assert result.gauges[-1]["corner y"] == pytest.approx(lam, rel=1e-9)
    # 1e-6 h_c of penetration allowed (h_c = 1/3) against a travel of 0.026
    assert result.gauges[-1]["holder travel"] == pytest.approx(1 - lam, rel=2e-5)
