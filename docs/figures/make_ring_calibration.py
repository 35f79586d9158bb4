"""The ring-test calibration chart of docs/sweeps.md from a friction sweep.

    skfem-rkpm sweep ring --vary tools.platen.friction=0,0.05,0.1,0.15,0.2,0.3,stick \\
        --set geometry.divisions=[9,6] --set steps.count=25 --set discretization.locking=fbar \\
        --set output.fields=false --set output.figures=false --out results/ring-sweep
    skfem-rkpm sweep ring --vary tools.platen.friction=0.12 \\
        --set geometry.divisions=[9,6] --set steps.count=25 --set discretization.locking=fbar \\
        --set output.fields=false --set output.figures=false --out results/ring-check
    python docs/figures/make_ring_calibration.py results/ring-sweep results/ring-check

The second sweep is a "measurement": a ring with μ = 0.12, a value that is
not on the chart; its point at 40 % height reduction is read back.
"""

import sys
from pathlib import Path

import numpy as np

from skfem_rkpm.runs.calibration import friction_from_measurement, plot_calibration, sweep_curves


def main(sweep, check=None, reduction=40.0):
    """Draw the chart; with ``check``, read its run's μ back at ``reduction`` %."""
    curves = sweep_curves(sweep)
    measurement = None
    if check is not None:
        (mu_true, (hr, idc)), = sweep_curves(check).items()
        point = float(np.interp(reduction, hr, idc))
        mu = friction_from_measurement(curves, reduction, point)
        print(f"ring with μ = {mu_true}: {point:.2f} % inner diameter change at "
              f"{reduction:g} % height reduction reads μ = {mu:.4f}")
        measurement = (reduction, point, mu)
    for key, (hr, idc) in curves.items():
        print(f"μ = {key}: inner diameter change at 25/50 % height reduction "
              f"{np.interp(25, hr, idc):.2f} / {np.interp(50, hr, idc):.2f} %")
    path = Path(__file__).parent / "ring_calibration_sweep.png"
    plot_calibration(curves, path, measurement,
                     title="Ring test, RKPM, 9 x 6 cells (quarter model)")
    print(f"wrote {path}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
