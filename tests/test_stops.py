"""A run that stops says how far it got, what failed and where that point is
now, and which option would go further (console and status.txt)."""

import csv
import re

import numpy as np
import pytest

import skfem_rkpm.runs.runner as runner
from skfem_rkpm.runs.cli import main
from skfem_rkpm.runs.scene import builtin_scenes, load_scene

# the ring pressed to 85 % of its height in 10 steps on a coarse mesh, two
# cut-backs allowed: FEM Q1 folds an element near the platen at 77 %
FOLDING = ["geometry.divisions=[6,4]", "steps.count=10", "tools.platen.motion=[0.0,-17.0]",
           "steps.max_cutbacks=2", "output.fields=false", "output.figures=false"]


def ring(settings):
    return load_scene(builtin_scenes()["ring"], settings)


def test_a_folded_element_is_named_with_where_it_is_now_and_what_goes_further(tmp_path):
    sim = runner.build(ring(FOLDING), "fem")
    result = runner.run(sim, tmp_path, progress=False)
    assert not result.completed
    status = (tmp_path / "status.txt").read_text()
    assert status.startswith(result.message)
    rows = list(csv.DictReader(open(tmp_path / "history.csv", newline="")))
    t = float(rows[-1]["t"])
    # how far: the last converged load factor and its height reduction
    # (17 mm of platen travel on the ring's 20 mm half height, per unit t)
    reached = re.search(r"reached t = ([\d.]+) of 1 \(([\d.]+) % height reduction\) in "
                        r"(\d+) converged steps \(the scene has 10\)", status)
    assert reached, status
    assert float(reached[1]) == pytest.approx(t, rel=1e-3)
    assert float(reached[2]) == pytest.approx(100 * t * 17.0 / 20.0, abs=0.05)
    assert int(reached[3]) == len(rows)
    # what failed: the cell and point, where they started and are now
    cause = re.search(r"cause: det F <= 0: .* in cell (\d+) \(point (\d+)\) at X = "
                      r"\(([-\d.e]+), ([-\d.e]+)\); that point is now at x = "
                      r"\(([-\d.e]+), ([-\d.e]+)\)", status)
    assert cause, status
    X = np.array([float(cause[3]), float(cause[4])])
    u = (sim.basis.probes(X[:, None]) @ result.d).ravel()  # an independent evaluation
    np.testing.assert_allclose([float(cause[5]), float(cause[6])], X + u, rtol=1e-3,
                               atol=1e-3 * 20.0)  # the 4 digits printed
    # which option: FEM elements fold, RKPM is the way on
    assert "to go further: the elements fold: try --method rkpm" in status
    assert "--set steps.count=20" in status


def test_the_console_shows_the_report_and_counts_only_finished_scene_steps(tmp_path, capsys):
    code = main(["run", "ring", "--method", "fem", "--quiet", "--out", str(tmp_path / "r"),
                 *[f"--set={s}" for s in FOLDING]])
    assert code == 1
    out, err = capsys.readouterr()
    assert re.search(r": 9 of 10 steps \(in \d+ sub-steps\)", out), out
    # 9 finished scene steps: t ≥ 0.9 (the last cut-back sets the digits)
    assert re.search(r"stopped: reached t = 0\.9\d* of 1", err) and "to go further:" in err


def test_rkpm_on_background_cells_is_pointed_to_nodal_integration(tmp_path):
    """99.5 % of the height in 10 steps, no cut-back, μ = 0.3: the first step
    folds RKPM's background cells (6 Gauss points with det F < 0)."""
    sim = runner.build(ring(FOLDING[:2] + ["tools.platen.motion=[0.0,-19.9]",
                                           "steps.max_cutbacks=0", "output.fields=false",
                                           "output.figures=false",
                                           "tools.platen.friction=0.3"]), "rkpm")
    result = runner.run(sim, tmp_path, progress=False)
    assert not result.completed
    assert "cause: det F <= 0" in result.report
    assert ("the background cells that carry the quadrature fold: try --set "
            "discretization.integration=scni") in result.report
    assert "re-referencing (--set discretization.rereference=0.5" in result.report


def test_a_rereferenced_run_counts_its_rebuilds_and_the_initial_height(tmp_path):
    """The folding ring with re-referencing: the rebuilds are named in the
    status, and the height reduction is the platen travel over the initial
    height (not that of the last reference)."""
    sim = runner.build(ring(FOLDING + ["discretization.rereference=0.9",
                                       "discretization.rereference_supports=spacing"]),
                       "rkpm")
    result = runner.run(sim, tmp_path, progress=False)
    status = (tmp_path / "status.txt").read_text()
    rebuilds = re.search(r"re-referenced (\d+) times \(at t = ", status)
    assert rebuilds and int(rebuilds[1]) == len(sim.rereferenced.events) >= 1, status
    t = result.history[-1].t
    if not result.completed:
        reached = re.search(r"reached t = [\d.]+ of 1 \(([\d.]+) % height reduction\)",
                            status)
        assert float(reached[1]) == pytest.approx(100 * t * 17.0 / 20.0, abs=0.05)
        assert "re-referencing (--set" not in status  # it is on already
    rows = list(csv.DictReader(open(tmp_path / "history.csv", newline="")))
    assert len(rows) == len(result.history)
    # the gauges stay in the initial frame: the platen-side top point has
    # come down with the platen (stick: it touches from the first step)
    assert float(rows[-1]["outer_top y"]) == pytest.approx(20.0 - 17.0 * t, abs=0.05)


def test_newton_that_does_not_converge_is_named_with_more_steps(tmp_path):
    sim = runner.build(ring(["geometry.divisions=[6,4]", "steps.count=2",
                             "steps.max_iterations=2", "steps.max_cutbacks=0",
                             "output.fields=false", "output.figures=false"]), "fem")
    result = runner.run(sim, tmp_path, progress=False)
    assert not result.completed
    assert "cause: Newton did not converge: no convergence in 2 iterations" in result.report
    # the iterations a step are named with the number the run allowed (2),
    # besides more steps and cut-backs; the console and status.txt say the same
    advice = ("to go further: more Newton iterations a step (--set steps.max_iterations=4; "
              "this run allowed 2), more load steps (--set steps.count=4) or more "
              "cut-backs (--set steps.max_cutbacks=4)")
    assert advice in result.report
    assert advice in (tmp_path / "status.txt").read_text()
    assert "reached t = 0 of 1 (0.0 % height reduction) in 0 converged steps" in result.report
    # the last converged state (at rest) folds nowhere: 24 drawn cells, and the
    # map's 25 samples in each of them at det F = 1 to round-off
    state = re.search(r"last converged state: no drawn cell folded \(of 24\); the FEM map "
                      r"itself is valid: det F >= ([\d.e+-]+) at all 600 sample points",
                      result.report)
    assert state, result.report
    assert float(state[1]) == pytest.approx(1.0, abs=1e-12)


def test_a_refused_rebuild_is_named_and_the_run_goes_on(tmp_path):
    """Supports kept on the coarse ring (a = 1.2 h): the sheared particles of
    the current configuration leave Gauss points covered by two particles,
    the rebuild is refused, and the run goes on on its last reference (here
    the initial one: Lagrangian RKPM); its status says so, and a report
    points to re-dilated supports."""
    sim = runner.build(ring(FOLDING + ["discretization.rereference=0.9"]), "rkpm")
    result = runner.run(sim, tmp_path, progress=False)
    status = (tmp_path / "status.txt").read_text()
    assert "not re-referenced; a rebuild at t = 0.3 was refused (moment matrix" in status
    assert "the run went on on the last reference" in status
    assert result.history[-1].t > 0.3
    if not result.completed:
        assert "--set discretization.rereference_supports=spacing" in result.report
