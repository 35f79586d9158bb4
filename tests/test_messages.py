"""Messages a user can act on: tools set up the wrong way round, a final
state with inverted cells, the command line's help, and the figures and
report of a run (labelled axes, units, the ring's calibration curve)."""

import warnings

import numpy as np
import pytest

import skfem_rkpm.runs.runner as runner
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.scene import SceneError, builtin_scenes, load_scene

SMALL = ["steps.count=6", "geometry.divisions=[6,4]", "discretization.support=12",
         "output.figures=false"]
RING = builtin_scenes()["ring"]


def small_ring(*more):
    return runner.build(load_scene(RING, SMALL + list(more)))


def test_a_platen_normal_pointing_away_is_refused_at_build(tmp_path, capsys):
    # before: the run started and every step failed with "det F = -7.3 <= 0"
    args = ["run", "ring", *(f"--set={s}" for s in SMALL), "--set",
            "tools.platen.normal=[0.0, 1.0]", "--out", str(tmp_path / "o"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    # the slave points (top, left, right: 7 + 4 + 4 particles) lie 0 to 20 mm
    # below the platen at y = 20; the particle spacing is 5 mm
    assert err == ("error: the normal of tools.platen points away from the part; flip it "
                   "(at t = 0 all 15 slave points are behind its surface, up to 20 deep, "
                   "4 particle spacings)\n")
    assert not (tmp_path / "o" / "history.csv").exists()


def test_a_polyline_the_wrong_way_round_is_refused():
    # a top die over the ring runs in -x (the part on its left, below it)
    with pytest.raises(SceneError, match=r"the points of tools.platen run the wrong way "
                                         r"\(the part must be on their left\); reverse "
                                         r"their order"):
        small_ring('tools.platen.kind="polyline"', "tools.platen.points=[[0, 20], [70, 20]]")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        small_ring('tools.platen.kind="polyline"', "tools.platen.points=[[70, 20], [0, 20]]")


def test_a_tool_touching_the_part_at_the_start_need_not_be_wrong():
    # the built-in ring: the platen touches the top at t = 0 (gaps 0 there)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        small_ring()


def test_a_tool_that_starts_in_contact_and_moves_away_warns(tmp_path, capsys):
    with pytest.warns(UserWarning, match=r"tool 'platen' starts in contact with the part "
                                         r"and moves away from it: the smallest gap to the "
                                         r"undeformed slave boundary grows from 0 at t = 0 "
                                         r"to 10 at t = 1"):
        small_ring("tools.platen.motion=[0.0, 10.0]")
    args = ["run", "ring", *(f"--set={s}" for s in SMALL), "--set",
            "tools.platen.motion=[0.0, 10.0]", "--out", str(tmp_path / "o"), "--quiet"]
    assert main(args) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("warning:")]
    assert len(lines) == 1 and "moves away from it" in lines[0]


def test_corner_jacobians_are_det_F_of_q1_at_the_corners():
    """Against scikit-fem's own Q1 deformation gradient evaluated at the
    reference corners (a quadrature rule of the four corner points)."""
    from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

    from skfem_rkpm.runs.io import corner_jacobians

    mesh = MeshQuad.init_tensor(np.linspace(0, 2, 4), np.linspace(0, 1, 3))
    corners = np.array([[0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]])  # order of mesh.t
    basis = Basis(mesh, ElementVector(ElementQuad1()), quadrature=(corners, np.ones(4)))
    rng = np.random.default_rng(3)
    u = 0.4 * rng.standard_normal((mesh.nvertices, 2))  # folds some cells
    d = u.ravel()  # skfem's vector dofs: (u_x, u_y) of vertex 0, then vertex 1, ...
    grad = basis.interpolate(d).grad  # (2, 2, ncells, 4)
    F = np.eye(2)[:, :, None, None] + grad
    expected = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    J = corner_jacobians(mesh, u)
    assert (J < 0).any() and (J > 0).any()
    np.testing.assert_allclose(J, expected, rtol=1e-12, atol=1e-12)  # round-off only


def test_a_final_state_with_a_folded_cell_is_not_just_completed():
    # before: the FEM ring said "completed" with a corner det F of -0.12
    sim = small_ring()  # 6 x 4 cells of 5 x 5 mm; (60, 20) is the outer top corner
    assert runner.final_state_message(sim, np.zeros(sim.basis.N)) == "completed"
    from skfem_rkpm.runs.io import nodal_displacements

    corner = int(np.flatnonzero((sim.mesh.p[0] == 60) & (sim.mesh.p[1] == 20))[0])
    # RK coefficients are not vertex values: solve for coefficients whose
    # vertex displacements move only that corner, to (52, 12), across the
    # diagonal of its cell
    u = np.zeros((sim.mesh.nvertices, 2))
    u[corner] = [-8.0, -8.0]
    A = np.column_stack([nodal_displacements(sim.basis, e).ravel()
                         for e in np.eye(sim.basis.N)])
    d = np.linalg.solve(A, u.ravel())
    message = runner.final_state_message(sim, d)
    # edges from (52, 12) to the neighbours (55, 20) and (60, 15): cross product
    # 3 * 3 - 8 * 8 = -55 against 25 undeformed: det F = -2.2
    assert message.startswith("completed with inverted cells: det F = -2.2 <= 0 at the "
                              "corner X = (60, 20) of cell ")
    assert "(1 of 24 cells folded)" in message


@pytest.mark.parametrize("command, default", [
    ("run", "results/SCENE-METHOD"), ("compare", "results/SCENE-compare"),
    ("sweep", "results/SCENE-sweep")])
def test_help_is_plain_text_and_names_the_default_folder(command, default, capsys):
    from pathlib import Path

    from skfem_rkpm.runs.cli import _default_out

    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert "`" not in text and ":func:" not in text and "``" not in text
    assert f"default {default}" in text
    method = "rkpm" if command == "run" else None
    suffix = "" if command == "run" else f"-{command}"
    scene = Path("ring.toml")
    assert str(_default_out(scene, method, [], suffix)) == default.replace(
        "SCENE", "ring").replace("METHOD", "rkpm")
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "`" not in capsys.readouterr().out


@pytest.fixture(scope="module")
def ring_run(tmp_path_factory):
    """The small ring run by the command line with its figures (about 4 s)."""
    out = tmp_path_factory.mktemp("ring")
    args = ["run", "ring", *(f"--set={s}" for s in SMALL[:-1]), "--set=output.fields=false",
            "--out", str(out), "--quiet"]
    assert main(args) == 0
    sim = small_ring()
    return out, sim, runner.run(sim, progress=False)


def test_the_ring_run_draws_its_figures_and_calibration_curve(ring_run):
    out, _, _ = ring_run
    for name in ("deformed.png", "forces.png", "calibration.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_drawn_curves_are_those_of_history_csv(ring_run):
    """Height reduction and inner-diameter change of the figures against
    calibration.ring_curve, which reads history.csv (the platen's gauge
    column and the followed point) independently."""
    from skfem_rkpm.runs.calibration import ring_curve
    from skfem_rkpm.runs.plot import height_reduction, inner_diameter_change

    out, sim, result = ring_run
    reduction, change = ring_curve(out / "history.csv")
    t = [r.t for r in result.history]
    np.testing.assert_allclose(height_reduction(sim, t), reduction[1:], rtol=1e-12)
    np.testing.assert_allclose(inner_diameter_change(sim, result.gauges), change[1:],
                               rtol=1e-9)  # the CSV holds 17 digits: round-off
    assert reduction[-1] == pytest.approx(50.0)  # 10 mm travel over the 20 mm half height


def test_figures_have_units_readable_labels_and_the_friction(ring_run):
    import matplotlib.pyplot as plt

    from skfem_rkpm.runs.plot import run_figures

    _, sim, result = ring_run
    figures = run_figures(sim, result)
    deformed = figures["deformed.png"].axes[0]
    assert (deformed.get_xlabel(), deformed.get_ylabel()) == ("r (mm)", "z (mm)")
    assert deformed.get_title() == "Ring compression (RKPM), μ = 0.15\nheight reduction 50 %"
    forces = figures["forces.png"].axes[0]
    assert forces.get_xlabel() == "height reduction (%)"
    assert forces.get_ylabel() == "force on the part (N, full ring)"
    labels = [line.get_label() for line in forces.get_lines()]
    assert labels == ["platen, force z", "boundary bottom, reaction z"]  # not bottom[1]
    calibration = figures["calibration.png"].axes[0]
    assert calibration.get_xlabel() == "height reduction (%)"
    assert calibration.get_ylabel() == "inner diameter change (%)"
    for fig in figures.values():
        plt.close(fig)
    # another unit, plane strain, frictionless, a tool that does not move
    sim = small_ring('model.length_unit="m"', 'model.force_unit="kN"',
                     'model.type="plane_strain"', "tools.platen.friction=0",
                     "tools.platen.motion=[0, 0]", "boundary.top.displacement=[0, -2]")
    result = runner.run(sim, progress=False)
    figures = run_figures(sim, result)
    deformed = figures["deformed.png"].axes[0]
    assert (deformed.get_xlabel(), deformed.get_ylabel()) == ("x (m)", "y (m)")
    assert deformed.get_title() == "Ring compression (RKPM), μ = 0\nt = 1"
    forces = figures["forces.png"].axes[0]
    assert forces.get_xlabel() == "load factor t"
    assert forces.get_ylabel() == "force on the part (kN, per unit thickness)"
    assert "calibration.png" not in figures
    for fig in figures.values():
        plt.close(fig)


def test_the_comparison_report_names_its_settings_and_the_inner_diameter(ring_run, tmp_path):
    from skfem_rkpm.runs.report import write_comparison

    _, sim, result = ring_run
    report = write_comparison({"rkpm": (sim, result)}, tmp_path, SMALL, "ring.toml")
    text = report.read_text()
    assert "- scene: `ring.toml`" in text
    for setting in SMALL:
        assert f"- `--set {setting}`" in text
    assert "axisymmetric, μ = 0.15, 6 load steps" in text
    change = 100 * (result.gauges[-1]["inner_mid x"] - 30.0) / 30.0
    assert f"| inner diameter change [%] | {change:.4g} |" in text
    assert "| height reduction [%] | 50 |" in text
    assert "| platen, force z [N] |" in text
