"""scikit-fem scripts with only their ``Basis`` line (and ``asm``'s import)
changed: error and CPU time with FEM, the interpolating RK basis and, for
comparison, the standard RK basis through the same unchanged script.

The scripts and references are those of ``tests/test_basis_line.py`` (ex01,
ex09, ex03, ex14, ex11, ex10, ex19, ex43 of scikit-fem's documentation, and a
cantilever beam on hexahedra).
Relative error of the quantity each test checks; CPU seconds
(``time.process_time``) of the whole script, basis included, median of
``--repeat`` runs.  A script that raises shows the error's class.

Run:  python benchmarks/basis_line.py          (~1 minute)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import pathlib  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

import skfem  # noqa: E402
from _timing import median_cpu  # noqa: E402

import skfem_rkpm  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
import test_basis_line as scripts  # noqa: E402


def standard_basis(mesh, element, **fem_only):
    return skfem_rkpm.RKBasis(mesh, element)


BASES = {"FEM": (skfem.Basis, skfem.asm),
         "RK interpolating": (scripts.rk_basis, skfem_rkpm.asm),
         "RK standard": (standard_basis, skfem_rkpm.asm)}


def crank_nicolson_error(result):
    steps, centre = result
    return abs(centre / scripts.crank_nicolson_factor()**steps - 1)


def relative(read, reference):
    return lambda result: abs(read(result) / reference - 1)


ERRORS = {
    "ex01": relative(lambda r: r[0], scripts.square_centre_series()),
    "ex09": relative(lambda r: r[0], scripts.CUBE_CENTRE),
    "ex03": relative(lambda r: r[0], scripts.BEAM_EIGENVALUES[0]),
    "ex14": relative(lambda r: r, 8 / 3),
    "ex11": relative(lambda r: r[0], scripts.BLOCK_ENERGY),
    "cantilever": relative(lambda r: r, scripts.BEAM_TIP),
    "ex10": relative(lambda r: r[0], scripts.SURFACE_CENTRE),
    "ex19": crank_nicolson_error,
    "ex43": relative(lambda r: r[1], scripts.TWIST_ENERGY),
}


def measure(script, basis, asm, repeat):
    def once():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                return script(basis, asm)
            except Exception as err:  # a script that fails is a result here
                return err
    return median_cpu(once, repeat)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print("| example | " + " | ".join(f"{k} error | {k} s" for k in BASES) + " |")
    print("|---|" + "---|---|" * len(BASES))
    for name, error in ERRORS.items():
        cells = []
        for basis, asm in BASES.values():
            seconds, result = measure(getattr(scripts, name), basis, asm, args.repeat)
            text = (type(result).__name__ if isinstance(result, Exception)
                    else f"{error(result):.2e}")
            cells += [text, f"{seconds:.2f}"]
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
