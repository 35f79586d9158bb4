"""scikit-fem's published examples ex15, ex17 and ex35 with FEM and with the
documented swap ``RKBasis(mesh, element, interpolating=True)`` (for ex17 and
ex35 also with the supports cut at the materials, ``interfaces=True``): the error of
each quantity against its closed form and the CPU time of the whole example
(``time.process_time``, median of ``--repeat`` runs, basis included).  The
example drivers are those of ``tests/test_published_examples.py``.

Run:  python benchmarks/published_examples.py          (~1 minute)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import pathlib  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
from _timing import median_cpu  # noqa: E402
from skfem import Basis  # noqa: E402

_tests = pathlib.Path(__file__).resolve().parents[1] / "tests"
sys.path.insert(0, str(_tests))
_spec = importlib.util.spec_from_file_location("published", _tests / "test_published_examples.py")
ex = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ex)


def ex15(kind):
    _, x = ex.ex15(kind)
    return f"max u error {abs(np.max(x) - 10 / 81):.1e}"


def ex17(kind, n, conductivity, **options):
    exact = ex.wire_centre(*conductivity)
    core = ex.mended if kind == "rk" else \
        (lambda b, m: Basis(m, b.elem, elements=m.subdomains["core"]))
    value = ex.ex17(kind, ex.wire_mesh(n), conductivity, core=core, **options)
    return f"T(0) error {abs(value - exact):.1e}"


def ex35(kind, n, **options):
    L, C, _ = ex.ex35(kind, ex.coax_mesh(n), **options)
    L_exact, C_exact = ex.coax_exact()
    Z = np.sqrt(L / C) / np.sqrt(L_exact / C_exact) - 1
    return (f"L {abs(L / L_exact - 1):.1e}, C {abs(C / C_exact - 1):.1e}, "
            f"Z {abs(Z):.1e} (rel.)")


CASES = [
    ("ex15 1D Poisson, 9 cells, P1", lambda k: ex15(k)),
    ("ex17 wire, k = 101 / 11, 289 vertices, Q1", lambda k: ex17(k, 8, (101.0, 11.0))),
    ("ex17 wire, k = 101 / 11, 1089 vertices, Q1", lambda k: ex17(k, 16, (101.0, 11.0))),
    ("ex17 wire, k = 11 / 11, 289 vertices, Q1", lambda k: ex17(k, 8, (11.0, 11.0))),
    ("ex35 coax, 841 vertices, P1", lambda k: ex35(k, 1)),
    ("ex35 coax, 3249 vertices, P1", lambda k: ex35(k, 2)),
    ("ex17, 289 vertices, RK interfaces=True", lambda k: ex17(k, 8, (101.0, 11.0),
                                                              interfaces=True)),
    ("ex17, 1089 vertices, RK interfaces=True", lambda k: ex17(k, 16, (101.0, 11.0),
                                                               interfaces=True)),
    ("ex35, 841 vertices, RK interfaces=True", lambda k: ex35(k, 1, interfaces=True)),
    ("ex35, 3249 vertices, RK interfaces=True", lambda k: ex35(k, 2, interfaces=True)),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores, "
          f"CPU seconds, median of {args.repeat}\n")
    print("| example | FEM s | FEM | RK s | RK |")
    print("|---|---|---|---|---|")
    for title, run in CASES:
        (fs, fr), (rs, rr) = (median_cpu(lambda: run(kind), args.repeat)
                              for kind in ("fem", "rk"))
        print(f"| {title} | {fs:.2f} | {fr} | {rs:.2f} | {rr} |", flush=True)
    print(f"\nload average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
