"""The dynamic keys of a scene: ``material.density``, ``[initial]`` and
``[dynamics]``; their checks against each other and against the rest of
the scene.

``[dynamics] scheme`` is ``"static"`` (the default: load steps solved by
Newton, no inertia), ``"implicit"`` (Newmark's trapezoidal rule or HHT-α
with the lumped mass, :class:`~skfem_rkpm.solvers.time_integration.Newmark`,
in the Newton loop: Eq. 3.38) or ``"explicit"`` (central differences with
the lumped mass, :class:`~skfem_rkpm.solvers.explicit.CentralDifference`);
dynamic time is in seconds.  A static scene does not carry these keys at all: the
validated scene of a file without them is the one of the versions before
them (its content hash, :func:`skfem_rkpm.runs.checkpoint.run_identity`,
is unchanged), so :func:`dynamics_of` and :func:`initial_of` fill in the
defaults for readers.
"""

from .scene_geometry import model_dimension
from .scene_values import Key, _positive

__all__ = ["DENSITY", "DYNAMICS_SCHEMA", "INITIAL_SCHEMA", "INTEGRATORS", "OPTIONAL_SECTIONS",
           "SCHEMES", "check_dynamics", "dynamics_of", "initial_of", "is_dynamic"]

#: the accepted values of ``dynamics.scheme``
SCHEMES = ("static", "implicit", "explicit")

#: the accepted values of ``dynamics.integrator`` (implicit scheme)
INTEGRATORS = ("newmark", "hht")


def _scheme(v):
    return None if v in SCHEMES else f"must be one of {', '.join(map(repr, SCHEMES))}"


def _integrator(v):
    return None if v in INTEGRATORS else (
        f"must be one of {', '.join(map(repr, INTEGRATORS))} (newmark: the trapezoidal "
        f"rule; hht: HHT-α, numerical damping of the high modes)")


def _alpha(v):
    return None if -1.0 / 3.0 - 1e-12 <= v <= 0.0 else (
        "must lie in [-1/3, 0] (0: no damping, the trapezoidal rule; -1/3: the most "
        "damping of high modes; -0.05 to -0.1 is usual)")


def _safety(v):
    return None if 0.0 < v <= 1.0 else "must lie in (0, 1]: a fraction of the stable step"


def _velocity(v):
    return None if len(v) in (2, 3) else "needs two values [x, y] (3D: three, [x, y, z])"


#: ``material.density``; omitted from a scene that does not give it
DENSITY = Key("float", check=_positive,
              doc="reference density ρ₀ (mass per volume in the scene's units: t/mm³ in "
                  "mm, N, MPa, s, e.g. 8.93e-9 for copper); needed by dynamics.scheme = "
                  "\"implicit\" and \"explicit\"")

DYNAMICS_SCHEMA = {
    "scheme": Key("str", "static", check=_scheme,
                  doc="static: load steps solved by Newton, without inertia ([steps]); "
                      "implicit: time steps of dynamics.time_step solved by Newton with "
                      "the inertia of the lumped mass (Newmark or HHT-α, Eq. 3.38; "
                      "[steps] gives the tolerance, iterations and cut-backs); "
                      "explicit: central differences with the lumped mass, no linear "
                      "solve; time in seconds (docs/dynamics.md) (static, implicit, "
                      "explicit)"),
    "integrator": Key("str", check=_integrator,
                      doc="implicit: newmark (the trapezoidal rule, β = 1/4, γ = 1/2: no "
                          "numerical damping, energy kept to the Newton tolerance; the "
                          "default) or hht (HHT-α with dynamics.alpha: damps the high "
                          "modes)"),
    "alpha": Key("float", check=_alpha,
                 doc="implicit, integrator = \"hht\": α in [-1/3, 0] (default -0.1); "
                     "β = (1 − α)²/4, γ = 1/2 − α"),
    "duration": Key("float", check=_positive,
                    doc="implicit, explicit: the time simulated (s); tools reach their "
                        "motion and "
                        "load histories their t = 1 at its end"),
    "output_interval": Key("float", check=_positive,
                           doc="implicit, explicit: time between two rows of "
                               "history.csv and two "
                               "field outputs (s; default: a tenth of duration); a row "
                               "is written at the first step at or after each output "
                               "time, and at the end"),
    "safety": Key("float", 0.9, check=_safety,
                  doc="explicit: the step is safety · 2/ω_max, ω_max estimated on the "
                      "current configuration (the body's M⁻¹K and a bound of the "
                      "penalty contact)"),
    "estimate_every": Key("int", 50, check=_positive,
                          doc="explicit: most steps between two estimates of the stable "
                              "step (fewer while ω_max grows fast)"),
    "time_step": Key("float", check=_positive,
                     doc="implicit (required): the time step (s), at most duration; "
                         "duration is split into equal steps no longer than it, and "
                         "Newton's step control halves a step that does not converge "
                         "(steps.max_cutbacks) and lets it grow back to it; explicit: "
                         "a fixed step instead of the estimated one; above the stable "
                         "step the run blows up"),
}

INITIAL_SCHEMA = {
    "velocity": Key("list[float]", check=_velocity,
                    doc="initial velocity of the body, uniform: [x, y] (axisymmetric: "
                        "[r, z]; 3D: [x, y, z]) in length units per second; needs "
                        "dynamics.scheme = \"implicit\" or \"explicit\""),
}

#: sections that a scene carries only when its file (or a --set) gives them
OPTIONAL_SECTIONS = {"dynamics": DYNAMICS_SCHEMA, "initial": INITIAL_SCHEMA}


def _defaults(schema):
    return {key: spec.default for key, spec in schema.items()}


def dynamics_of(scene):
    """The ``[dynamics]`` section of a validated scene, defaults filled in."""
    return {**_defaults(DYNAMICS_SCHEMA), **(scene.get("dynamics") or {})}


def initial_of(scene):
    """The ``[initial]`` section of a validated scene, defaults filled in."""
    return {**_defaults(INITIAL_SCHEMA), **(scene.get("initial") or {})}


def is_dynamic(scene):
    """True for a scene with a time-integration scheme (not ``"static"``)."""
    return dynamics_of(scene)["scheme"] != "static"


def check_dynamics(scene, fail):
    """The dynamic keys against each other and the rest of the scene;
    ``fail(path, message)`` raises the :class:`SceneError`."""
    dynamics, initial = dynamics_of(scene), initial_of(scene)
    scheme = dynamics["scheme"]
    dim = model_dimension(scene["model"]["type"])
    velocity = initial["velocity"]
    if velocity is not None and len(velocity) != dim:
        fail("initial.velocity", f"needs {dim} components (model.type = "
                                 f"{scene['model']['type']!r}), not {len(velocity)}")
    _check_ramps(scene, scheme, fail)
    if scheme == "static":
        if velocity is not None:
            fail("initial.velocity", "an initial velocity needs a dynamics scheme: set "
                                     "dynamics.scheme = \"explicit\" or \"implicit\" "
                                     "(and material.density, dynamics.duration)")
        for key in ("duration", "output_interval", "time_step", "integrator", "alpha"):
            if dynamics[key] is not None:
                fail(f"dynamics.{key}", "only for a dynamics scheme: set dynamics.scheme "
                                        "= \"explicit\" or \"implicit\", or remove the key")
        return
    if scheme == "explicit":
        for key in ("integrator", "alpha"):
            if dynamics[key] is not None:
                fail(f"dynamics.{key}", "only for dynamics.scheme = \"implicit\" (the "
                                        "explicit scheme is central differences): remove "
                                        "the key")
    if scene["material"].get("density") is None:
        fail("dynamics.scheme", f"{scheme} dynamics needs the mass: give material.density "
                                f"(t/mm³ in mm, N, MPa, s; 8.93e-9 for copper)")
    if dynamics["duration"] is None:
        fail("dynamics", f"{scheme} dynamics needs 'duration', the time simulated (s)")
    interval = dynamics["output_interval"]
    if interval is not None and interval > dynamics["duration"]:
        fail("dynamics.output_interval", f"is longer than duration "
                                         f"({dynamics['duration']!r} s): at most the duration")
    if scheme == "implicit":
        _check_implicit(scene, dynamics, fail)
        return
    _check_explicit_conditions(scene, fail)


def _check_ramps(scene, scheme, fail):
    """``tools.NAME.ramp``: a smooth start in time, of a tool that moves."""
    for name, section in scene.items():
        if not name.startswith("tools.") or section.get("ramp") is None:
            continue
        if scheme == "static":
            fail(f"{name}.ramp", "a smooth start in time needs a dynamics scheme (static "
                                 "load steps follow the motion linearly): set "
                                 "dynamics.scheme = \"implicit\" or \"explicit\", or "
                                 "remove the key")
        if not any(section.get("motion") or ()) and section.get("rotation") is None:
            fail(f"{name}.ramp", "the tool does not move: give it a motion (or a "
                                 "rotation), or remove the key")


def _check_implicit(scene, dynamics, fail):
    """The implicit scheme's keys: a time step within the duration, α only
    with HHT-α."""
    step = dynamics["time_step"]
    if step is None:
        fail("dynamics", "implicit dynamics needs 'time_step', the time step (s), e.g. a "
                         "hundredth of duration (the step control cuts it back when "
                         "Newton does not converge)")
    if step > dynamics["duration"]:
        fail("dynamics.time_step", f"is longer than duration ({dynamics['duration']!r} "
                                   f"s): at most the duration")
    if dynamics["duration"] / step > 1e6:
        fail("dynamics.time_step", f"gives {dynamics['duration'] / step:.3g} steps over "
                                   f"the duration: at most 1e6 (a longer step)")
    if dynamics["alpha"] is not None and (dynamics["integrator"] or "newmark") != "hht":
        fail("dynamics.alpha", "only for integrator = \"hht\" (newmark is α = 0): set "
                               "dynamics.integrator = \"hht\" or remove alpha")
    for name, section in scene.items():
        if name.startswith("tools.") and section.get("force") is not None:
            fail(f"{name}.force", "a force-driven tool is not available in implicit "
                                  "dynamics: give the tool a motion")


def _check_explicit_conditions(scene, fail):
    """What the explicit scheme holds: homogeneous nodal fixes and symmetry
    planes (projected), dead pressures and tractions, penalty contact with
    tools that move as prescribed."""
    for name, section in scene.items():
        if name.startswith("tools."):
            if section.get("enforcement") == "augmented":
                fail(f"{name}.enforcement", "explicit dynamics needs penalty contact (an "
                                            "augmented Lagrangian needs equilibrium "
                                            "iterations): set enforcement = \"penalty\"")
            if section.get("force") is not None:
                fail(f"{name}.force", "a force-driven tool needs equilibrium iterations; "
                                      "in explicit dynamics give the tool a motion")
        if not name.startswith("boundary."):
            continue
        constrained = section["fix"] or section["symmetry"] or section["displacement"]
        if constrained and section["method"] != "nodal":
            fail(f"{name}.method", "explicit dynamics holds conditions on nodal values "
                                   "(the transformation method): set method = \"nodal\"")
        if section["displacement"] is not None:
            fail(f"{name}.displacement", "explicit dynamics holds homogeneous conditions "
                                         "only: use fix (zero displacement) or move a "
                                         "rigid tool")
        if section["follower"]:
            fail(f"{name}.follower", "explicit dynamics takes dead pressures only: remove "
                                     "follower")
