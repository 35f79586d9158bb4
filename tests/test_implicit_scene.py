"""Scenes with ``dynamics.scheme = "implicit"``: the keys, their errors and
a short Taylor bar against the explicit one."""

import csv

import numpy as np
import pytest

from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.explicit_run import run_explicit
from skfem_rkpm.runs.implicit_run import implicit_alpha, implicit_steps, run_implicit
from skfem_rkpm.runs.scene import SceneError, builtin_scenes, load_scene

DURATION = 10e-6  # the first 10 µs of the impact: the plastic wave is under way
SHORT = [f"dynamics.duration={DURATION}", f"dynamics.output_interval={DURATION / 4}",
         "geometry.divisions=[3, 25]", "output.fields=false", "output.figures=false"]
IMPLICIT = ['dynamics.scheme="implicit"', "dynamics.time_step=0.25e-6"]


def taylor(settings):
    return load_scene(builtin_scenes()["taylor_bar"], SHORT + settings)


@pytest.fixture(scope="module")
def implicit_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("implicit") / "run"
    result = run_implicit(build(taylor(IMPLICIT), None), out, progress=False)
    return result, out


@pytest.fixture(scope="module")
def explicit_rows():
    return run_explicit(build(taylor([]), None), progress=False).rows


def test_implicit_taylor_bar_follows_the_explicit_one(implicit_run, explicit_rows):
    """The same impact by the trapezoidal rule (40 steps of 0.25 µs, a
    Courant number c0 Δt / h ≈ 0.7 along the bar) and by central
    differences (0.9 of the stable step): the two differ by their time
    discretization only.  The shortening of the bar at 10 µs (2.24 mm) is
    a momentum balance over the whole bar and agrees within 1 % (measured
    0.1 %); the spreading of the foot (2.2 mm) is a local corner quantity,
    where the implicit step smooths the first contact of the mantle:
    within 3 % (measured 1.1 %; with 0.1 µs steps 0.9 %)."""
    result, _ = implicit_run
    assert result.completed, result.report
    final, reference = result.rows[-1], explicit_rows[-1]
    assert final["time"] == pytest.approx(DURATION, rel=1e-9)
    assert reference["time"] == pytest.approx(DURATION, rel=1e-9)
    shortening = 32.4 - final["top y"]
    assert shortening > 1.5  # the bar has been hit: 227 m/s over 10 µs is 2.27 mm
    assert shortening == pytest.approx(32.4 - reference["top y"], rel=0.01)
    assert final["foot x"] - 3.2 == pytest.approx(reference["foot x"] - 3.2, rel=0.03)


def test_implicit_taylor_bar_energy_balance(implicit_run):
    """The trapezoidal rule keeps ``T + W_int + W_contact − W_ext`` to the
    Newton tolerance (mechanics/energy.py): within 1 % of the peak kinetic
    energy, the issue's bound, while a fifth of the energy has gone into
    plastic work.  The initial kinetic energy is ½ ρ π R² L v0² (the
    lumped mass keeps the total mass)."""
    result, _ = implicit_run
    rows = result.rows
    kinetic = np.array([r["kinetic"] for r in rows])
    exact = 0.5 * 8.93e-9 * np.pi * 3.2 ** 2 * 32.4 * 227e3 ** 2
    assert kinetic[0] == pytest.approx(exact, rel=1e-9)
    errors = np.array([r["balance error"] for r in rows])
    assert np.abs(errors).max() < 0.01 * kinetic.max()
    assert rows[-1]["plastic"] > 0.1 * kinetic[0]
    assert rows[-1]["internal"] == pytest.approx(rows[-1]["elastic"] + rows[-1]["plastic"])
    assert [r["step"] for r in rows] == [0, 10, 20, 30, 40]


def test_implicit_run_folder(implicit_run):
    """history.csv has a row per output time with the energies and the
    followed points; status.txt says how the run ended."""
    result, out = implicit_run
    with open(out / "history.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == len(result.rows) == 5
    for key in ("time", "kinetic", "internal", "contact", "external work", "balance",
                "reaction wall y", "foot x", "top y", "newton iterations"):
        assert key in rows[0]
    assert float(rows[-1]["top y"]) == pytest.approx(result.rows[-1]["top y"], rel=1e-12)
    assert (out / "status.txt").read_text().startswith("completed")
    assert (out / "scene.toml").is_file()


def test_implicit_keys():
    scene = taylor(IMPLICIT + ['dynamics.integrator="hht"', "dynamics.alpha=-0.05"])
    assert implicit_alpha(scene) == -0.05
    assert implicit_alpha(taylor(IMPLICIT + ['dynamics.integrator="hht"'])) == -0.1
    assert implicit_alpha(taylor(IMPLICIT)) == 0.0
    assert implicit_steps(scene) == 40
    assert implicit_steps(taylor(['dynamics.scheme="implicit"', "dynamics.time_step=3e-6"])) == 4


@pytest.mark.parametrize("settings, key, words", [
    (['dynamics.scheme="implicit"'], "dynamics", "time_step"),
    (['dynamics.scheme="implicit"', "dynamics.time_step=20e-6"], "dynamics.time_step",
     "longer than duration"),
    (IMPLICIT + ['dynamics.integrator="rk4"'], "dynamics.integrator", "newmark"),
    (IMPLICIT + ["dynamics.alpha=-0.1"], "dynamics.alpha", "hht"),
    (IMPLICIT + ['dynamics.integrator="hht"', "dynamics.alpha=0.2"], "dynamics.alpha",
     "[-1/3, 0]"),
    (['dynamics.integrator="hht"'], "dynamics.integrator", "implicit"),
    (['dynamics.scheme="implicite"'], "dynamics.scheme", "implicit"),
])
def test_bad_implicit_keys(settings, key, words):
    with pytest.raises(SceneError) as info:
        taylor(settings)
    assert key in str(info.value) and words in str(info.value)


def test_implicit_needs_density_and_refuses_resume(tmp_path):
    text = (builtin_scenes()["taylor_bar"].read_text()
            .replace("density = 8.93e-9", ""))
    path = tmp_path / "bar.toml"
    path.write_text(text)
    with pytest.raises(SceneError, match="material.density"):
        load_scene(path, IMPLICIT)
    with pytest.raises(ValueError, match="resume"):
        run_implicit(build(taylor(IMPLICIT), None), tmp_path / "run", resume=True)
    assert not (tmp_path / "run").exists()


def _short_run(settings, out=None):
    scene = taylor(IMPLICIT + ["dynamics.duration=2e-6", "dynamics.output_interval=1e-6"]
                   + settings)
    return run_implicit(build(scene, None), out, progress=False)


def test_hht_dissipates_and_the_trapezoidal_rule_does_not():
    """Over 8 steps of 0.25 µs the trapezoidal rule keeps the balance to
    the Newton tolerance (measured 4e-8 of the kinetic energy); HHT-α
    removes energy (the balance falls: measured 0.2 % for α = −0.1,
    0.3 % for α = −0.3), more with a larger |α|, and stays within the 1 %."""
    errors = {}
    for label, settings in (("newmark", []), ("hht", ['dynamics.integrator="hht"']),
                            ("hht-0.3", ['dynamics.integrator="hht"', "dynamics.alpha=-0.3"])):
        result = _short_run(settings)
        assert result.completed, result.report
        peak = max(r["kinetic"] for r in result.rows)
        errors[label] = result.rows[-1]["balance error"] / peak
    assert abs(errors["newmark"]) < 1e-5
    assert errors["hht-0.3"] < errors["hht"] < -100 * abs(errors["newmark"])
    assert errors["hht-0.3"] > -0.01


def test_a_step_that_fails_stops_with_a_report(tmp_path):
    """One Newton iteration cannot converge the impact (the residual of the
    first iteration is 6e-6, tolerance 1e-6): the run stops and says so."""
    result = _short_run(["steps.max_iterations=1", "steps.max_cutbacks=1"], tmp_path / "run")
    assert not result.completed
    status = (tmp_path / "run" / "status.txt").read_text()
    assert status.startswith("stopped: reached t = 0 s of 2e-06 s in 0 converged time steps")
    assert "Newton did not converge" in status
    assert "--set dynamics.time_step=1.25e-07" in status
    assert "--set steps.max_iterations=2" in status
