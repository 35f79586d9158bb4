"""The dynamic keys of a scene: ``material.density``, ``[initial]`` and
``[dynamics]``; their checks against each other and against the rest of
the scene.

``[dynamics] scheme`` is ``"static"`` (the default: load steps solved by
Newton, no inertia) or ``"explicit"`` (central differences with the lumped
mass, :class:`~skfem_rkpm.solvers.explicit.CentralDifference`; time in
seconds).  A static scene does not carry these keys at all: the
validated scene of a file without them is the one of the versions before
them (its content hash, :func:`skfem_rkpm.runs.checkpoint.run_identity`,
is unchanged), so :func:`dynamics_of` and :func:`initial_of` fill in the
defaults for readers.
"""

from .scene_geometry import model_dimension
from .scene_values import Key, _positive

__all__ = ["DENSITY", "DYNAMICS_SCHEMA", "INITIAL_SCHEMA", "OPTIONAL_SECTIONS", "SCHEMES",
           "check_dynamics", "dynamics_of", "initial_of", "is_dynamic"]

#: the accepted values of ``dynamics.scheme``
SCHEMES = ("static", "explicit")


def _scheme(v):
    if v in SCHEMES:
        return None
    if v == "implicit":
        return (f"implicit time integration is not available in scenes; accepted schemes: "
                f"{', '.join(map(repr, SCHEMES))}")
    return f"must be one of {', '.join(map(repr, SCHEMES))}"


def _safety(v):
    return None if 0.0 < v <= 1.0 else "must lie in (0, 1]: a fraction of the stable step"


def _velocity(v):
    return None if len(v) in (2, 3) else "needs two values [x, y] (3D: three, [x, y, z])"


#: ``material.density``; omitted from a scene that does not give it
DENSITY = Key("float", check=_positive,
              doc="reference density ρ₀ (mass per volume in the scene's units: t/mm³ in "
                  "mm, N, MPa, s, e.g. 8.93e-9 for copper); needed by dynamics.scheme = "
                  "\"explicit\"")

DYNAMICS_SCHEMA = {
    "scheme": Key("str", "static", check=_scheme,
                  doc="static: load steps solved by Newton, without inertia ([steps]); "
                      "explicit: central differences with the lumped mass, no linear "
                      "solve, time in seconds (docs/dynamics.md) (static, explicit)"),
    "duration": Key("float", check=_positive,
                    doc="explicit: the time simulated (s); tools reach their motion and "
                        "load histories their t = 1 at its end"),
    "output_interval": Key("float", check=_positive,
                           doc="explicit: time between two rows of history.csv and two "
                               "field outputs (s; default: a tenth of duration); a row "
                               "is written at the first step at or after each output "
                               "time, and at the end"),
    "safety": Key("float", 0.9, check=_safety,
                  doc="explicit: the step is safety · 2/ω_max, ω_max estimated on the "
                      "current configuration (the body's M⁻¹K and a bound of the "
                      "penalty contact)"),
    "estimate_every": Key("int", 50, check=_positive,
                          doc="explicit: steps between two estimates of the stable step"),
    "time_step": Key("float", check=_positive,
                     doc="explicit: a fixed step (s) instead of the estimated one; above "
                         "the stable step the run blows up"),
}

INITIAL_SCHEMA = {
    "velocity": Key("list[float]", check=_velocity,
                    doc="initial velocity of the body, uniform: [x, y] (axisymmetric: "
                        "[r, z]; 3D: [x, y, z]) in length units per second; needs "
                        "dynamics.scheme = \"explicit\""),
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
    if scheme == "static":
        if velocity is not None:
            fail("initial.velocity", "an initial velocity needs a dynamics scheme: set "
                                     "dynamics.scheme = \"explicit\" (and "
                                     "material.density, dynamics.duration)")
        for key in ("duration", "output_interval", "time_step"):
            if dynamics[key] is not None:
                fail(f"dynamics.{key}", "only for a dynamics scheme: set dynamics.scheme "
                                        "= \"explicit\", or remove the key")
        return
    if scene["material"].get("density") is None:
        fail("dynamics.scheme", f"{scheme} dynamics needs the mass: give material.density "
                                f"(t/mm³ in mm, N, MPa, s; 8.93e-9 for copper)")
    if dynamics["duration"] is None:
        fail("dynamics", f"{scheme} dynamics needs 'duration', the time simulated (s)")
    interval = dynamics["output_interval"]
    if interval is not None and interval > dynamics["duration"]:
        fail("dynamics.output_interval", f"is longer than duration "
                                         f"({dynamics['duration']!r} s): at most the duration")
    _check_explicit_conditions(scene, fail)


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
