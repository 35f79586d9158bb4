"""The billet_3d scene in CalculiX 2.20, for a side-by-side with our runs.

Writes a CalculiX input deck of the ``billet_3d`` scene (one eighth of a
40 x 20 x 30 mm billet, E = 288 GPa, nu = 0.3, perfectly plastic at
100 MPa, upset to half its height by a rigid platen with Coulomb friction
mu = 0.3; symmetry planes x = 0, y = 0, z = 0), runs ``ccx`` on it in a
folder of its own, and reads the platen force and the free corner's
position at every converged increment from the ``.dat`` file.

The platen is a rigid body (one layer of C3D8 bricks tied to a reference
node that moves 7.5 mm down); contact is node-to-surface with a linear
penalty and a stick slope for friction.  The billet's faces x = 20,
y = 10 and z = 15 are the slave nodes, as in the scene, since the free
sides roll onto the platen.

Element types: C3D8I (incompatible modes), C3D8R (reduced integration,
hourglass control) and C3D20R (quadratic, reduced), at any division.
The forces printed are for the whole billet (4 x the modelled eighth).

Needs ``ccx`` on the PATH (Debian: ``apt-get install calculix-ccx``).

Run:  python benchmarks/calculix/billet_3d.py                       (C3D8I, 8 x 4 x 6)
      python benchmarks/calculix/billet_3d.py --element C3D20R --divisions 8 4 6
      python benchmarks/calculix/billet_3d.py --deck-only --out /tmp/deck
"""

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SIZE = (20.0, 10.0, 15.0)          # the modelled eighth, mm
E, NU, YIELD = 288e3, 0.3, 100.0   # MPa
MU = 0.3
PRESS = 7.5                        # platen travel, mm (50 % height reduction)
STEPS = 50


def grid_nodes(divisions, quadratic):
    """Node numbers on the (2n+1)-point grid of a quadratic mesh, or the (n+1)-point one."""
    k = 2 if quadratic else 1
    shape = tuple(k * n + 1 for n in divisions)
    index = np.indices(shape).reshape(3, -1).T
    odd = (index % 2 == 1).sum(axis=1) if quadratic else np.zeros(len(index), int)
    keep = odd <= 1                 # a 20-node brick has no face or cell centres
    numbers = np.zeros(len(index), int)
    numbers[keep] = np.arange(1, keep.sum() + 1)
    xyz = index[keep] * (np.array(SIZE) / (k * np.array(divisions)))
    return numbers.reshape(shape), xyz


def brick_connectivity(numbers, divisions, quadratic):
    """CalculiX node order of every brick: corners 1-8, then the edges of C3D20."""
    k = 2 if quadratic else 1
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
               (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
             (0, 4), (1, 5), (2, 6), (3, 7)]
    cells = []
    for i, j, m in np.ndindex(*divisions):
        base = np.array([i, j, m]) * k
        points = [base + k * np.array(c) for c in corners]
        if quadratic:
            points += [(points[a] + points[b]) // 2 for a, b in edges]
        cells.append([numbers[tuple(p)] for p in points])
    return np.array(cells)


def deck(element, divisions, stiffness, stick_slope):
    """The input deck as text."""
    quadratic = element.startswith("C3D20")
    numbers, xyz = grid_nodes(divisions, quadratic)
    cells = brick_connectivity(numbers, divisions, quadratic)
    n_nodes = len(xyz)
    tol = 1e-9
    sets = {name: np.flatnonzero(cond) + 1 for name, cond in {
        "XMIN": xyz[:, 0] < tol, "YMIN": xyz[:, 1] < tol, "ZMIN": xyz[:, 2] < tol,
        "XMAX": xyz[:, 0] > SIZE[0] - tol, "YMAX": xyz[:, 1] > SIZE[1] - tol,
        "ZMAX": xyz[:, 2] > SIZE[2] - tol}.items()}
    corner = numbers[-1, -1, 0]
    top_corner = numbers[-1, -1, -1]
    slaves = np.union1d(np.union1d(sets["XMAX"], sets["YMAX"]), sets["ZMAX"])

    # the platen: 2 x 2 bricks, 1 mm thick, over [-2, 36] x [-2, 22] at z = 15
    px, py = np.linspace(-2.0, 36.0, 3), np.linspace(-2.0, 22.0, 3)
    pz = np.array([SIZE[2], SIZE[2] + 1.0])
    platen_xyz = np.array([(x, y, z) for z in pz for y in py for x in px])
    platen_num = n_nodes + 1 + np.arange(len(platen_xyz)).reshape(2, 3, 3)
    platen_cells = []
    for j, i in np.ndindex(2, 2):
        b, t = platen_num[0], platen_num[1]
        platen_cells.append([b[j, i], b[j, i + 1], b[j + 1, i + 1], b[j + 1, i],
                             t[j, i], t[j, i + 1], t[j + 1, i + 1], t[j + 1, i]])
    ref, rot = n_nodes + len(platen_xyz) + 1, n_nodes + len(platen_xyz) + 2

    lines = ["** billet_3d: one eighth of a 40 x 20 x 30 mm billet upset by 50 %",
             "*NODE"]
    lines += [f"{n}, {x:.10g}, {y:.10g}, {z:.10g}" for n, (x, y, z) in enumerate(xyz, 1)]
    lines += [f"{n}, {x:.10g}, {y:.10g}, {z:.10g}"
              for n, (x, y, z) in zip(platen_num.ravel(), platen_xyz)]
    lines += [f"{ref}, 0., 0., {SIZE[2]:.10g}", f"{rot}, 0., 0., {SIZE[2]:.10g}"]
    lines.append(f"*ELEMENT, TYPE={element}, ELSET=BILLET")
    lines += [chunked(e, c) for e, c in enumerate(cells, 1)]
    lines.append("*ELEMENT, TYPE=C3D8, ELSET=PLATEN")
    lines += [chunked(e, c) for e, c in enumerate(platen_cells, len(cells) + 1)]
    for name, nodes in sets.items():
        lines += [f"*NSET, NSET={name}"] + rows(nodes)
    lines += ["*NSET, NSET=SLAVES"] + rows(slaves)
    lines += ["*NSET, NSET=REF", str(ref), "*NSET, NSET=CORNER", str(corner),
              "*NSET, NSET=TOPCORNER", str(top_corner)]
    lines += ["*SURFACE, NAME=SLAVE, TYPE=NODE", "SLAVES",
              "*SURFACE, NAME=MASTER", "PLATEN, S1",
              "*RIGID BODY, ELSET=PLATEN, REF NODE=%d, ROT NODE=%d" % (ref, rot),
              "*MATERIAL, NAME=STEEL", "*ELASTIC", f"{E:.10g}, {NU}",
              "*PLASTIC", f"{YIELD:.10g}, 0.",
              "*SOLID SECTION, ELSET=BILLET, MATERIAL=STEEL",
              "*MATERIAL, NAME=RIGID", "*ELASTIC", f"{E:.10g}, {NU}",
              "*SOLID SECTION, ELSET=PLATEN, MATERIAL=RIGID",
              "*SURFACE INTERACTION, NAME=PRESS",
              "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{stiffness:.10g}",
              "*FRICTION", f"{MU}, {stick_slope:.10g}",
              "*CONTACT PAIR, INTERACTION=PRESS, TYPE=NODE TO SURFACE",
              "SLAVE, MASTER",
              "*BOUNDARY", "XMIN, 1, 1", "YMIN, 2, 2", "ZMIN, 3, 3",
              f"{rot}, 1, 3", f"{ref}, 1, 2",
              "*STEP, NLGEOM, INC=10000",
              "*STATIC", f"{1.0 / STEPS:.10g}, 1., 1e-6, {1.0 / STEPS:.10g}",
              "*BOUNDARY", f"{ref}, 3, 3, {-PRESS:.10g}",
              "*NODE PRINT, NSET=REF", "RF, U",
              "*NODE PRINT, NSET=CORNER", "U",
              "*NODE PRINT, NSET=TOPCORNER", "U",
              "*NODE PRINT, NSET=ZMIN, TOTALS=ONLY", "RF",
              "*END STEP"]
    return "\n".join(lines) + "\n"


def chunked(number, nodes):
    """An element line; CalculiX takes at most 16 entries per line."""
    entries = [str(number)] + [str(n) for n in nodes]
    return ",\n".join(", ".join(entries[i:i + 16]) for i in range(0, len(entries), 16))


def rows(numbers):
    return [", ".join(str(n) for n in numbers[i:i + 16]) for i in range(0, len(numbers), 16)]


def read_dat(path):
    """Per converged increment: time, platen force on the eighth, corner displacement."""
    blocks, current = {}, None
    for line in Path(path).read_text().splitlines():
        words = line.split()
        if "for set" in line and "time" in line:
            name = words[words.index("set") + 1]
            kind = words[0]
            time = float(words[-1])
            current = blocks.setdefault((kind, name), {}).setdefault(time, [])
        elif current is not None and len(words) == 4:
            try:
                current.append([float(w) for w in words[1:]])
            except ValueError:
                current = None
        elif not words:
            continue
        else:
            current = None
    times = sorted(blocks[("forces", "REF")])
    force = np.array([blocks[("forces", "REF")][t][0][2] for t in times])
    corner = np.array([blocks[("displacements", "CORNER")][t][0] for t in times])
    return np.array(times), force, corner


def run(element, divisions, stiffness, stick_slope, folder):
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "billet.inp").write_text(deck(element, divisions, stiffness, stick_slope))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(["ccx", "-i", "billet"], cwd=folder, capture_output=True,
                          text=True, env={"OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    (folder / "ccx.log").write_text(done.stdout + done.stderr)
    if done.returncode != 0 or "Job finished" not in done.stdout:
        raise SystemExit(f"ccx failed in {folder}; see {folder / 'ccx.log'}")
    times, force, corner = read_dat(folder / "billet.dat")
    return times, force, corner, cpu, done.stdout.count("increment size=")


def at(times, values, t):
    return float(np.interp(t, times, values))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--element", default="C3D8I", choices=["C3D8I", "C3D8R", "C3D20R"])
    parser.add_argument("--divisions", type=int, nargs=3, default=[8, 4, 6])
    parser.add_argument("--stiffness", type=float, default=1e6,
                        help="contact penalty, N/mm^3 (default 1e6, ~10 E / h)")
    parser.add_argument("--stick-slope", type=float, default=1e5,
                        help="tangential penalty, N/mm^3")
    parser.add_argument("--out", help="folder for the deck and ccx's files (default: a temporary one)")
    parser.add_argument("--deck-only", action="store_true")
    args = parser.parse_args(argv)
    if args.deck_only:
        if not args.out:
            parser.error("--deck-only needs --out")
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "billet.inp").write_text(deck(args.element, args.divisions, args.stiffness,
                                             args.stick_slope))
        print(out / "billet.inp")
        return
    if shutil.which("ccx") is None:
        raise SystemExit("ccx not found: install CalculiX (Debian: apt-get install calculix-ccx)")
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(args.out) if args.out else Path(scratch)
        times, force, corner, cpu, _ = run(args.element, args.divisions, args.stiffness,
                                           args.stick_slope, folder)
    whole = -4e-3 * force                       # kN on the whole billet
    print(f"{args.element} {'x'.join(map(str, args.divisions))}: CPU {cpu:.1f} s, "
          f"{len(times)} increments; force at 25 % {at(times, whole, 0.5):.1f} kN, "
          f"at 50 % {whole[-1]:.1f} kN (t = {times[-1]:.3f}); corner at 50 % "
          f"({SIZE[0] + corner[-1, 0]:.2f}, {SIZE[1] + corner[-1, 1]:.2f}) mm")


if __name__ == "__main__":
    sys.exit(main())
