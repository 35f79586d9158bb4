"""Volumetric locking control against exact answers: ``locking = "none"``
and ``"fbar"`` for RKPM, FEM Q1 and FEM Q2, and nodal integration (SCNI
with α = 1e-3 and 0, and with Voronoi cells) on three cases with a known
answer, each written as a scene (docs/plasticity.md, "Which locking
control").

* Prandtl's flat punch: a rigid, frictionless flat punch of half width
  a = 1 pressed into a perfectly plastic plane-strain block (half model,
  6a x 6a); the mean punch pressure at collapse is p = (2 + π) k,
  k = σ_y/√3 (Prandtl 1920; Hill, *The Mathematical Theory of
  Plasticity*, 1950, ch. VIII).
* Plane-strain compression between frictionless platens: homogeneous,
  p = 2k on the current area at every strain once yielded.
* Cook's membrane, elastic-plastic, finite strain, plane strain (Simo &
  Armero 1992, Int. J. Numer. Meth. Engng 33, 1413-1449, section 5.4):
  E = 206.9, ν = 0.29, σ_y = 0.45 + 0.265 (1 - exp(-16.93 ε̄ᵖ)) + 0.12924 ε̄ᵖ
  (our ``voce`` law), a shear traction 0.3125 on the right edge (total load
  5), left edge clamped; the tip deflection of the mixed and enhanced
  elements converges to 6.9-7.0 (the band we check; solids4foam's
  finite-volume tutorial reports 7.4 with a neo-Hookean elastic part).

and the built-in scenes punch, upsetting, ring (μ = 0.15 and stick) at full
resolution against their converged answers (docs/forming_scenes.md,
docs/ring.md).

Usage::

    PYTHONPATH=. python benchmarks/locking_study.py [prandtl prandtl_fine
        compression cook cook_fine punch upsetting ring_0.15 ring_stick]

prints one row per case, method and locking control (the answer, its
ratio to the exact one or the reference, and the CPU seconds of the run).
The table and the rule it led to: docs/plasticity.md, "Which locking
control".
"""

import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np

from skfem_rkpm.runs.build import build
from skfem_rkpm.runs.runner import run
from skfem_rkpm.runs.scene import builtin_scenes, load_scene, parse_scene
from _whole_runs import ring_id_change

SIGMA_Y = 100.0
K_SHEAR = SIGMA_Y / np.sqrt(3.0)

DISCRETIZATIONS = {
    "rkpm": ('[model]\nmethod = "rkpm"\n', 'dilation = 2.0\nquadrature = 4\n'),
    "fem_q1": ('[model]\nmethod = "fem"\n', 'element = "quad1"\nquadrature = 2\n'),
    "fem_q2": ('[model]\nmethod = "fem"\n', 'element = "quad2"\nquadrature = 4\n'),
    # nodal integration: one point per particle (F-bar has nothing to average)
    "scni": ('[model]\nmethod = "rkpm"\n',
             'dilation = 2.0\nintegration = "scni"\nstabilization = 1e-3\n'),
    "scni_0": ('[model]\nmethod = "rkpm"\n',
               'dilation = 2.0\nintegration = "scni"\nstabilization = 0.0\n'),
    "scni_vor": ('[model]\nmethod = "rkpm"\n', 'dilation = 2.0\nintegration = "scni"\n'
                 'stabilization = 1e-3\nsmoothing = "voronoi"\n'),
}
NODAL = ("scni", "scni_0", "scni_vor")

PRANDTL_GEO = """
h = {h};
Point(1) = {{0, 0, 0, 4 * h}};
Point(2) = {{6, 0, 0, 4 * h}};
Point(3) = {{6, 6, 0, 4 * h}};
Point(4) = {{1, 6, 0, h}};
Point(5) = {{0, 6, 0, h}};
Line(1) = {{1, 2}};
Line(2) = {{2, 3}};
Line(3) = {{3, 4}};
Line(4) = {{4, 5}};
Line(5) = {{5, 1}};
Curve Loop(1) = {{1, 2, 3, 4, 5}};
Plane Surface(1) = {{1}};
Physical Curve("bottom") = {{1}};
Physical Curve("right") = {{2}};
Physical Curve("free") = {{3}};
Physical Curve("punch") = {{4}};
Physical Curve("left") = {{5}};
Physical Surface("block") = {{1}};
Mesh.Algorithm = 8;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;
"""

PRANDTL = """
{model}type = "plane_strain"

[geometry]
kind = "gmsh"
file = "{geo}"

[discretization]
{disc}locking = "{locking}"

[material]
E = 1e6
nu = 0.3
yield = 100.0
hardening = "perfect"

[boundary.punch]           # smooth rigid punch: the face moves down, slides freely
displacement = {{y = -{travel}}}
method = "{how}"

[boundary.left]
fix = ["x"]
method = "{how}"

[boundary.bottom]
fix = ["y"]
method = "{how}"

[boundary.right]
fix = ["x"]
method = "{how}"

[steps]
count = 10
"""

COMPRESSION = """
{model}type = "plane_strain"

[geometry]
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [{n}, {n}]

[discretization]
{disc}locking = "{locking}"

[material]
E = 100e3
nu = 0.3
yield = 100.0
hardening = "perfect"

[boundary.left]
fix = ["x"]
method = "{how}"

[boundary.bottom]
fix = ["y"]
method = "{how}"

[boundary.top]
displacement = {{y = -0.3}}
method = "{how}"

[steps]
count = 6

[output]
points = {{ corner = [1.0, 1.0] }}
"""

COOK_GEO = """
n = {n};
Point(1) = {{0, 0, 0}};
Point(2) = {{48, 44, 0}};
Point(3) = {{48, 60, 0}};
Point(4) = {{0, 44, 0}};
Line(1) = {{1, 2}};
Line(2) = {{2, 3}};
Line(3) = {{3, 4}};
Line(4) = {{4, 1}};
Curve Loop(1) = {{1, 2, 3, 4}};
Plane Surface(1) = {{1}};
Transfinite Curve{{1, 2, 3, 4}} = n + 1;
Transfinite Surface{{1}};
Recombine Surface{{1}};
Physical Curve("bottom") = {{1}};
Physical Curve("right") = {{2}};
Physical Curve("top") = {{3}};
Physical Curve("left") = {{4}};
Physical Surface("membrane") = {{1}};
"""

COOK = """
{model}type = "plane_strain"

[geometry]
kind = "gmsh"
file = "{geo}"

[discretization]
{disc}locking = "{locking}"

[material]
E = 206.9
nu = 0.29
yield = 0.45
Q = 0.265                   # sigma_inf - sigma_y = 0.715 - 0.45
b = 16.93
hardening = "voce"
H = 0.12924

[boundary.left]
fix = ["x", "y"]
method = "{how}"

[boundary.right]
traction = [0.0, 0.3125]    # a dead shear load of 5 over the right edge (16 long)

[steps]
count = 30

[output]
points = {{ tip = [48.0, 60.0] }}
"""


def _scene(template, method, locking, **values):
    model, disc = DISCRETIZATIONS[method]
    how = "nodal" if method.startswith("fem") else "weak"
    return template.format(model=model, disc=disc, locking=locking, how=how, **values)


def _run(text, base=None):
    scene = parse_scene(text, base=base)
    sim = build(scene, trust_geo=False)
    start = time.process_time()
    result = run(sim, progress=False)
    return sim, result, time.process_time() - start


def prandtl(method, locking, h=0.125, travel=0.01):
    """Mean punch pressure / k at the end of the travel (1 % of a)."""
    with tempfile.TemporaryDirectory() as folder:
        geo = Path(folder) / "prandtl.geo"
        geo.write_text(PRANDTL_GEO.format(h=h))
        _, result, cpu = _run(_scene(PRANDTL, method, locking, geo=geo.name, travel=travel),
                              base=folder)
    force = [abs(r.reactions["punch[1]"]) for r in result.history]
    return force[-1] / 1.0 / K_SHEAR, 2 + np.pi, cpu, result


def compression(method, locking, n=4):
    """True platen pressure / k at 30 % shortening."""
    _, result, cpu = _run(_scene(COMPRESSION, method, locking, n=n))
    width = result.gauges[-1]["corner x"]
    return abs(result.history[-1].reactions["top[1]"]) / width / K_SHEAR, 2.0, cpu, result


def cook(method, locking, n=8):
    """Vertical deflection of the top right corner under the full load."""
    with tempfile.TemporaryDirectory() as folder:
        geo = Path(folder) / "cook.geo"
        geo.write_text(COOK_GEO.format(n=n))
        _, result, cpu = _run(_scene(COOK, method, locking, geo=geo.name), base=folder)
    return result.gauges[-1]["tip y"] - 60.0, 6.95, cpu, result


CASES = {"prandtl": prandtl, "compression": compression, "cook": cook,
         # the same on halved cells: does the answer converge to the exact one?
         "prandtl_fine": partial(prandtl, h=0.0625), "cook_fine": partial(cook, n=16)}

#: built-in scenes at their full resolution: (settings, what is measured,
#: converged reference of docs/ring.md (corner-refined ring, both methods)
#: and docs/forming_scenes.md)
SCENES = {
    "ring_0.15": (["tools.platen.friction=0.15"], "ID change % at 50 %",
                  {"rkpm": -29.91, "fem": -27.49}),
    "ring_stick": (['tools.platen.friction="stick"'], "ID change % at 50 %",
                   {"rkpm": -60.74, "fem": -60.84}),
    "punch": ([], "punch force N/mm at 30 mm", {"rkpm": 197.0, "fem": 196.9}),
    "upsetting": ([], "punch force kN at 16.8 mm", {"rkpm": 145.05, "fem": 146.08}),
}


def scene_case(name, method, locking):
    """One built-in scene run with the given locking control: the measured
    value at the end of the run (or where it stopped), the travel reached
    (fraction of the scene's), CPU seconds and the result."""
    settings, _, _ = SCENES[name]
    scene_name = name.split("_")[0]
    settings = [*settings, f'discretization.locking="{locking}"',
                "output.fields=false", "output.figures=false"]
    sim = build(load_scene(builtin_scenes()[scene_name], settings), method)
    start = time.process_time()
    result = run(sim, progress=False)
    cpu = time.process_time() - start
    last = result.history[-1]
    if scene_name == "ring":
        value = ring_id_change(result.gauges[-1])
    elif scene_name == "punch":
        value = -last.reactions["punch"][1]
    else:
        value = -last.reactions["punch"][1] / 1e3
    return value, last.t, cpu, result


def main_scenes(names):
    if not names:
        return
    print(f"{'scene':12s} {'method':7s} {'locking':7s} {'value':>8s} {'ref':>8s} "
          f"{'t':>5s} {'cpu s':>6s}  measure")
    for name in names:
        for method in ("rkpm", "fem"):
            for locking in ("none", "fbar"):
                value, t, cpu, result = scene_case(name, method, locking)
                _, measure, reference = SCENES[name]
                print(f"{name:12s} {method:7s} {locking:7s} {value:8.2f} "
                      f"{reference[method]:8.2f} {t:5.2f} {cpu:6.1f}  {measure}", flush=True)


def main(names):
    if not names:
        return
    print(f"{'case':12s} {'method':7s} {'locking':7s} {'answer':>8s} {'exact':>6s} "
          f"{'ratio':>6s} {'cpu s':>6s}  status")
    for name in names:
        for method in DISCRETIZATIONS:
            for locking in ("none",) if method in NODAL else ("none", "fbar"):
                value, exact, cpu, result = CASES[name](method, locking)
                status = "completed" if result.completed else result.message[:50]
                print(f"{name:12s} {method:7s} {locking:7s} {value:8.3f} {exact:6.3f} "
                      f"{value / exact:6.3f} {cpu:6.1f}  {status}", flush=True)


if __name__ == "__main__":
    names = sys.argv[1:] or [*CASES, *SCENES]
    main([n for n in names if n in CASES])
    main_scenes([n for n in names if n in SCENES])
