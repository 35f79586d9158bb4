"""Where the stability of each integration scheme breaks: support size and
distortion of the particles.

On a free 12 x 12 patch of particles (``rectangle(1, 1, 11, 11, perturb=p)``:
interior vertices moved at random by up to ``p`` of the spacing), linear
elasticity, for each scheme and normalized support:

* *extra zeros*: eigenvalues of the stiffness below 1e-10 of the largest,
  beyond the 3 rigid motions (spurious zero-energy modes);
* *λ_min* and *λ < 0.1*: the softest non-rigid mode's energy relative to its
  accurate energy (generalized eigenvalues ``K v = λ K_ref v``, ``K_ref``
  with Gauss points of degree 8 on the cells) and the number of modes below
  a tenth of it (low-energy modes);
* *patch*: the largest gradient error of the linear patch test (traction on
  the whole boundary; round-off where the scheme passes it).

Schemes: Gauss+VCI in its symmetric form (``vci_symmetric``: the eigenvalue
test needs a symmetric matrix; same corrected gradients as a test of the
patch), SCNI, SCNI with the default stabilization α = 1e-3 and with α = 1,
DNI.  The helpers are those of ``tests/test_nodal_integration.py`` and
``tests/test_patch.py``.

Run:  python benchmarks/nodal_stability.py          (~1 minute)
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import pathlib  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from skfem_rkpm import SingularMomentError  # noqa: E402
from skfem_rkpm.meshes import rectangle  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from test_nodal_integration import softest_modes  # noqa: E402
from test_patch import linear_field, rk_error  # noqa: E402

SCHEMES = [("Gauss+VCI (symmetric)", "vci_symmetric", 0.0), ("SCNI", "scni", 0.0),
           ("SCNI α=1e-3", "scni", 1e-3), ("SCNI α=1", "scni", 1.0), ("DNI", "dni", 0.0)]


def row(mesh, support, integration, alpha):
    try:
        zeros, lam = softest_modes(mesh, support, integration, alpha)
    except SingularMomentError as err:
        return f"basis fails: {str(err).split(':')[0]}"
    patch = rk_error(mesh, linear_field, 1, support, integration, 4)[1]
    return (f"{zeros - 3} | {lam.min():.3f} | {int(np.sum(lam < 0.1))} | {patch:.1e}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--supports", type=float, nargs="+", default=[1.2, 1.5, 2.0, 3.0])
    parser.add_argument("--distortions", type=float, nargs="+", default=[0.0, 0.2, 0.4])
    args = parser.parse_args()
    print("| scheme | support | distortion | extra zeros | λ_min | λ < 0.1 | patch |")
    print("|---|---|---|---|---|---|---|")
    for distortion in args.distortions:
        mesh = rectangle(1.0, 1.0, 11, 11, perturb=distortion).with_defaults()
        for support in args.supports:
            for name, integration, alpha in SCHEMES:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    text = row(mesh, support, integration, alpha)
                if text.startswith("basis fails"):
                    text = f"{text} | | | "
                print(f"| {name} | {support} | {distortion} | {text} |", flush=True)


if __name__ == "__main__":
    main()
