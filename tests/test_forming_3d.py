"""The built-in 3D forming scenes, coarse: the ring sector against the
axisymmetric ring (the whole 3D path: mesh, symmetry planes at an angle,
3D contact with friction, F-bar in 3D) and the rectangular billet."""

import csv

import numpy as np
import pytest

from skfem_rkpm.runs.cli import main

STEPS = ["steps.count=20"]


def run(tmp_path, scene, method, settings):
    out = tmp_path / f"{scene}-{method}"
    options = [x for s in settings for x in ("--set", s)]
    assert main(["run", scene, "--out", str(out), "--quiet", "--method", method,
                 *options]) == 0
    with open(out / "history.csv", newline="") as handle:
        return list(csv.DictReader(handle)), (out / "status.txt").read_text()


@pytest.mark.roundoff
def test_ring_sector_reproduces_the_axisymmetric_ring(tmp_path):
    """FEM (F-bar) on the same 5 x 4 section, μ = 0.15, to 50 % height
    reduction in 40 steps: the 15° sector (2 cells around, symmetry planes
    at 0° and 15°) gives the axisymmetric inner-diameter change to 0.1
    percentage points and the force of the full ring to 1 % (measured 0.019
    points and 0.38 %, the sector with the augmented law of the scene, the
    ring with the penalty law; the sector's facets are chords, 0.2 % less
    area at 7.5° per cell).  The load steps must be the same in both: the
    step path alone moves the change by 0.4 points (20 steps: -26.14 %
    against -25.74 % in 40), and in 20 steps Newton's cutbacks of the
    sector follow round-off (27 sub-steps and 0.13 points under OpenBLAS's
    SkylakeX kernels, 33 and 0.28 points under Sandybridge); in 40 steps
    neither run cuts back under the SkylakeX, Haswell, Sandybridge and
    Nehalem kernels, which agree to all printed digits.  At full resolution
    (15 x 10 x 6) the two agree to 0.01 points and 0.1 % (docs/forming_3d.md)."""
    steps = ["steps.count=40"]
    ring, _ = run(tmp_path, "ring", "fem", steps + ["geometry.divisions=[5, 4]"])
    sector, status = run(tmp_path, "ring_sector", "fem",
                         steps + ["geometry.divisions=[5, 2, 4]"])
    # equal step paths (no cutback in either), the premise of the 0.1 points
    assert [row["t"] for row in sector] == [row["t"] for row in ring], (
        "the step paths differ (Newton cut a step back): the comparison then "
        "includes their 0.1-0.4 points of step-path difference")
    assert status.startswith("completed") and float(sector[-1]["t"]) == 1.0
    change_2d = 100 * (float(ring[-1]["inner_mid x"]) / 30.0 - 1)
    change_3d = 100 * (float(sector[-1]["inner_mid x"]) / 30.0 - 1)
    assert change_2d < -20  # friction turns the inner surface inward
    assert abs(change_3d - change_2d) < 0.1
    force_2d = -float(ring[-1]["reaction platen y"])
    force_3d = -24 * float(sector[-1]["reaction platen z"])
    assert force_3d == pytest.approx(force_2d, rel=1e-2)
    # the sector stays axisymmetric: the inner point does not leave its plane
    assert abs(float(sector[-1]["inner_mid y"])) < 1e-9


def at(rows, t):
    return min(rows, key=lambda r: abs(float(r["t"]) - t))


def test_rectangular_billet_rkpm_against_fem(tmp_path):
    """4 x 2 x 3 cells, μ = 0.3, both with F-bar: at 25 % height reduction
    the platen forces of RKPM and FEM Hex1 agree to 2 % (measured 0.5 %),
    and both lie above the frictionless (homogeneous) force σ_y · 200 H0/H
    mm², which friction can only raise (measured 5-6 % above).  Friction
    resists the flow along the long side more, so the billet spreads most
    across its short side (least resistance): the short half-width grows
    beyond the homogeneous stretch, and by more than the long one."""
    rk, _ = run(tmp_path, "billet_3d", "rkpm", STEPS + ["geometry.divisions=[4, 2, 3]"])
    fem, _ = run(tmp_path, "billet_3d", "fem", STEPS + ["geometry.divisions=[4, 2, 3]"])
    frictionless = 100.0 * 200.0 / 0.75
    forces = [-float(at(rows, 0.5)["reaction platen z"]) for rows in (rk, fem)]
    assert forces[0] == pytest.approx(forces[1], rel=2e-2)
    assert min(forces) > frictionless
    row = at(rk, 0.5)
    long, short = float(row["edge_x x"]) / 20.0, float(row["edge_y y"]) / 10.0
    assert short > 1.0 / np.sqrt(0.75) and short > long > 1.0


def test_rkpm_without_fbar_upsets_the_billet_to_half_its_height(tmp_path):
    """Without F-bar, RKPM completes 50 % with no folded cell (with F-bar
    both RKPM and FEM fold the cells at the top corner that rolls onto the
    platen, docs/forming_3d.md); every step's force is above the
    frictionless force."""
    rows, status = run(tmp_path, "billet_3d", "rkpm",
                       STEPS + ["geometry.divisions=[4, 2, 3]",
                                'discretization.locking="none"'])
    assert status.strip() == "completed" and float(rows[-1]["t"]) == 1.0
    for row in rows:
        ratio = 15.0 / (15.0 - 7.5 * float(row["t"]))  # H0 / H
        if ratio > 1.01:  # fully plastic
            assert -float(row["reaction platen z"]) > 100.0 * 200.0 * ratio


@pytest.mark.parametrize("method", ["rkpm", "fem"])
def test_stretched_sheet_is_in_equilibrium_and_thins_at_the_pole(tmp_path, method):
    """The square sheet over the ball punch, coarse (8 x 8 x 1 cells, 10
    steps to 15 mm): the punch force is carried by the clamped edges (the
    symmetry planes carry no force along z), so their reactions balance it
    to the Newton tolerance (1e-6 of the largest force of the iteration,
    which may be an internal one: measured up to 2e-6 of the punch force,
    asserted 1e-5),
    likewise in x; the force grows with the travel; the sheet, stretched
    over the punch, is thinner at the pole than its 1 mm."""
    rows, status = run(tmp_path, "stretch_3d", method,
                       ["geometry.divisions=[8, 8, 1]", "steps.count=10"])
    assert status.strip() == "completed" and float(rows[-1]["t"]) == 1.0
    punch = np.array([float(r["reaction punch z"]) for r in rows])
    assert np.all(np.diff(punch) > 0) and punch[0] > 0
    for row in rows:
        for axis, k in (("z", 2), ("x", 0)):
            total = (float(row[f"reaction punch {axis}"]) + float(row[f"reaction xmax[{k}]"])
                     + float(row[f"reaction ymax[{k}]"])
                     + (float(row["reaction xmin[0]"]) if k == 0 else 0.0))
            assert abs(total) < 1e-5 * float(row["reaction punch z"])
    # the lower face at the pole follows the punch (z = 15 t - 1 at its top)
    thickness = float(rows[-1]["pole z"]) - (15.0 - 1.0)
    assert 0.5 < thickness < 0.98
