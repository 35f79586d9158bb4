"""Closest-point projection onto a triangulated 3D tool surface.

Setup: the unit sphere as an icosphere of 20480 triangles (``--resolution
160``; the outline of ``Sphere``), ``--points`` points (default 1e4) drawn
with uniform random directions and radii in a band: near the surface
(0.9-1.1, where contact happens), outside (1.1-4), inside (0.5-0.9) and
deep inside (0-0.5, the worst case: near the centre of a concave tool
every triangle is almost equally near, and all must be measured).  The
tree is built once (its time is given); each projection is timed
``--repeat`` times in CPU seconds (``time.process_time``, one core) and the
median is reported, with the largest difference to the analytic sphere's
gap (the faceting error, about h²/(6R)).

Run:  python benchmarks/surface_projection.py
      python benchmarks/surface_projection.py --points 1e5 --resolution 80
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from skfem_rkpm.mechanics.surfaces import Sphere  # noqa: E402
from skfem_rkpm.mechanics.triangulated import TriangulatedSurface  # noqa: E402

BANDS = {"near (0.9-1.1)": (0.9, 1.1), "outside (1.1-4)": (1.1, 4.0),
         "inside (0.5-0.9)": (0.5, 0.9), "deep inside (0-0.5)": (0.0, 0.5)}


def band_points(n, low, high, rng):
    v = rng.normal(size=(3, n))
    return v / np.linalg.norm(v, axis=0) * rng.uniform(low, high, n)


def median_time(function, repeat):
    times = []
    for _ in range(repeat):
        start = time.process_time()
        function()
        times.append(time.process_time() - start)
    return float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=float, default=1e4)
    parser.add_argument("--resolution", type=int, default=160)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    n = int(args.points)
    sphere = Sphere((0.0, 0.0, 0.0), 1.0)
    p, t = sphere.outline(resolution=args.resolution)
    start = time.process_time()
    surface = TriangulatedSurface(p.T, t.T)
    build = time.process_time() - start
    print(f"{surface.nfeatures} triangles, tree and pseudo-normals built in {build:.3f} s "
          f"CPU; {n} points; median of {args.repeat} runs; load {os.getloadavg()[0]:.2f}\n")
    print("| points | CPU s (median) | points/s | max abs(g_h - g) |")
    print("|---|---|---|---|")
    rng = np.random.default_rng(1)
    for label, (low, high) in BANDS.items():
        x = band_points(n, low, high, rng)
        seconds = median_time(lambda: surface.project(x), args.repeat)
        error = np.abs(surface.project(x).gap - sphere.project(x).gap).max()
        print(f"| {label} | {seconds:.3f} | {n / seconds:.3g} | {error:.2e} |")
    x = band_points(n, 0.9, 1.1, rng)
    seconds = median_time(lambda: sphere.project(x), args.repeat)
    print(f"| analytic Sphere, near | {seconds:.4f} | {n / seconds:.3g} | 0 |")


if __name__ == "__main__":
    main()
