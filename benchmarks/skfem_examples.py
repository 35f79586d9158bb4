"""scikit-fem's examples ex09, ex10, ex11, ex19 and ex43 with FEM and RK bases:
CPU time of the whole example (``time.process_time``, median of ``--repeat``
runs, basis construction included) and the error against the reference of
``tests/test_skfem_examples.py`` (series for ex09 and ex19, extrapolated fine
FEM runs for the others).  The example drivers are those of the tests.

Run:  python benchmarks/skfem_examples.py          (~2 minutes)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import pathlib  # noqa: E402

from _timing import median_cpu  # noqa: E402
from skfem import ElementQuad2  # noqa: E402

_path = pathlib.Path(__file__).resolve().parents[1] / "tests" / "test_skfem_examples.py"
_spec = importlib.util.spec_from_file_location("skfem_examples", _path)
ex = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ex)



def cube(kind):
    m, basis, _, _, x, _ = ex.poisson_cube(kind, 8)
    u = ex.nodal(basis, x)
    return f"u(centre) error {abs(u[ex.vertex(m, [.5, .5, .5])] - ex.CUBE_CENTRE):.1e}"


def block(kind):
    energy, displacement, m = ex.elastic_block(kind, 3)
    contraction = -displacement[1, ex.vertex(m, [0.5, 1.0, 0.5])]
    return (f"energy error {(energy - ex.BLOCK_ENERGY) / ex.BLOCK_ENERGY:.1e} rel., "
            f"contraction error {abs(contraction / ex.BLOCK_CONTRACTION - 1):.1e} rel.")


def surface(kind):
    its, centre, area, _, _ = ex.minimal_surface(kind, 5)
    return (f"{its} Newton steps, u(centre) error {abs(centre - ex.SURFACE_CENTRE):.1e}, "
            f"area error {abs(area - ex.SURFACE_AREA):.1e}")


def heat(kind, element=None):
    steps, centre = ex.heat(kind, 8, element)
    r = (1 - (1 - ex.THETA) * ex.DECAY * ex.DT) / (1 + ex.THETA * ex.DECAY * ex.DT)
    return f"{steps} steps, T(0) error {abs(centre / r**steps - 1):.1e} rel."


def bar(kind):
    its, energy, _, _, _ = ex.twisted_bar(kind)
    return (f"Newton steps per load step {its}, energy error "
            f"{abs(energy / ex.TWIST_ENERGY - 1):.1e} rel.")


CASES = [
    ("ex09 3D Poisson, 8³ cubes of tets, CG", cube, [("P1", "fem"), ("RK", "vci_symmetric")]),
    ("ex11 elastic block, 8³ hexahedra", block, [("Q1", "fem"), ("RK", "vci_symmetric")]),
    ("ex10 minimal surface, refined(5)", surface, [("P1", "fem"), ("RK", "vci")]),
    ("ex19 heat, Crank-Nicolson, 16×16", heat, [("Q1", "fem"), ("RK", "vci_symmetric")]),
    ("ex43 Neo-Hooke twist, 9×2×2 hexahedra", bar, [("Q1", "fem"), ("RK", "vci")]),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores, "
          f"CPU seconds, median of {args.repeat}\n")
    print("| example | basis | CPU s | result |")
    print("|---|---|---|---|")
    for title, run, kinds in CASES:
        for label, kind in kinds:
            seconds, result = median_cpu(lambda: run(kind), args.repeat)
            print(f"| {title} | {label} ({kind}) | {seconds:.2f} | {result} |", flush=True)
        if run is heat:
            seconds, result = median_cpu(lambda: heat("fem", ElementQuad2()), args.repeat)
            print(f"| {title} | Q2 (fem) | {seconds:.2f} | {result} |", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
