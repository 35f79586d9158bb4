"""Strong and weak scaling of the partitioned assembly, projected to 64-1024 ranks.

Reads the per-rank reports that ``benchmarks/partitioned_scaling.py`` wrote
(``/tmp/partitioned_reports_P.json``) for P = 1 and 2 (and 4 if present,
printed for comparison only: on 2 cores it oversubscribes them) and
projects the time of one Newton iteration and the peak memory per rank
with this model (every assumption is a command-line option):

* **local work** (shape tables, material update, assembly, the solves with
  the factor, line-search evaluations): the time per cell and iteration of
  the P = 1 run outside the factorization, times the cells per rank;
* **factorization** (MUMPS): ``t_f(1) (N/N_1)^flops / P^gamma``, ``gamma``
  fitted to the measured P = 1 and 2 (``--gamma`` overrides), ``flops`` =
  1.5 for nested dissection of a 2D mesh;
* **sums over the ranks**: ``evaluations`` allreduces of ``8 N`` bytes per
  iteration, ``2 log2(P) latency + 2 (P-1)/P 8 N / bandwidth`` each;
* **matrix entries sent** (COO assembly): the measured share of entries in
  rows of other ranks at P = 2, grown as ``sqrt(P / 2)`` (the perimeter of
  a part of a 2D bisection over its area), 12 bytes each, over
  ``bandwidth``;
* **memory per rank**: ``M_rep + M_part / P`` with ``M_rep`` and ``M_part``
  fitted to the P = 1 and 2 peaks; in weak scaling ``M_rep`` grows with the
  dofs (replicated vectors, the gathered VCI balancing matrix) at the rate
  ``--replicated-bytes-per-dof``.

Strong scaling keeps the measured problem; weak scaling keeps the cells per
rank of the P = 1 run and grows the problem with P.

Run:  python benchmarks/partitioned_projection.py
"""

import argparse
import json

import numpy as np


def load(ranks, folder):
    with open(f"{folder}/partitioned_reports_{ranks}.json") as handle:
        return json.load(handle)


def per_iteration(reports):
    """(local seconds, factor seconds) per iteration, slowest rank."""
    its = reports[0]["iterations"]
    factor = max(r["factor_seconds"] for r in reports) / max(reports[0]["factorizations"], 1)
    newton = max(r["newton"] for r in reports) / its
    return newton - factor * reports[0]["factorizations"] / its, factor


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", default="/tmp")
    parser.add_argument("--bandwidth", type=float, default=10e9, help="bytes/s per rank")
    parser.add_argument("--latency", type=float, default=2e-6, help="seconds per message")
    parser.add_argument("--evaluations", type=float, default=2.0,
                        help="internal-force sums per Newton iteration")
    parser.add_argument("--flops", type=float, default=1.5,
                        help="factorization cost grows as dofs^flops")
    parser.add_argument("--gamma", type=float, default=None)
    parser.add_argument("--replicated-bytes-per-dof", type=float, default=400.0)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 4, 64, 256, 1024])
    args = parser.parse_args()

    one, two = load(1, args.folder), load(2, args.folder)
    N1, cells1 = one[0]["dofs"], one[0]["cells"]
    local1, factor1 = per_iteration(one)
    local2, factor2 = per_iteration(two)
    gamma = args.gamma if args.gamma is not None else np.log2(factor1 / factor2)
    m1, m2 = max(r["peak_mb"] for r in one), max(r["peak_mb"] for r in two)
    m_part = 2 * (m1 - m2)
    m_rep = m1 - m_part
    remote2 = (sum(r["remote_entries"] for r in two)
               / max(sum(r["entries"] for r in two), 1))
    entries = sum(r["entries"] for r in one)
    print(f"measured: {N1} dofs, {cells1} cells; per iteration local {local1:.2f} s, "
          f"factor {factor1:.2f} s at P = 1; {local2:.2f} s and {factor2:.2f} s at P = 2 "
          f"(gamma = {gamma:.2f}); peaks {m1:.0f} and {m2:.0f} MB -> replicated "
          f"{m_rep:.0f} MB + {m_part:.0f} MB / P; {100 * remote2:.1f} % of the entries sent "
          f"at P = 2")

    def iteration(P, N, cells_per_rank):
        local = local1 * cells_per_rank / cells1
        factor = factor1 * (N / N1) ** args.flops / P ** gamma
        allreduce = args.evaluations * (2 * np.log2(P) * args.latency
                                        + 2 * (P - 1) / P * 8 * N / args.bandwidth)
        sent = (remote2 * np.sqrt(P / 2) * entries * (N / N1) / P * 12 / args.bandwidth
                if P > 1 else 0.0)
        return local, factor, allreduce, sent

    for title, weak in (("strong scaling (the measured problem)", False),
                        ("weak scaling (the P = 1 cells per rank)", True)):
        print(f"\n{title}")
        print("| P | dofs | local s | factor s | sums s | entries sent s | iteration s "
              f"| {'efficiency' if weak else 'speed-up'} | peak MB/rank |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for P in args.ranks:
            N = N1 * P if weak else N1
            cells = cells1 if weak else cells1 / P
            parts = iteration(P, N, cells)
            total = sum(parts)
            base = sum(iteration(1, N1, cells1))
            memory = (m_rep + args.replicated_bytes_per_dof * (N - N1) / 2**20
                      + m_part * cells / cells1)
            speed = base / total
            print(f"| {P} | {N:,} | {parts[0]:.3g} | {parts[1]:.3g} | {parts[2]:.2g} | "
                  f"{parts[3]:.2g} | {total:.3g} | {speed:.2f} | {memory:,.0f} |")


if __name__ == "__main__":
    main()
