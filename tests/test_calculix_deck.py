"""The CalculiX deck of benchmarks/calculix describes the billet_3d scene.

The side-by-side in docs/forming_3d.md is only a check of our runs if the
deck models the same billet: these tests read the built-in scene and the
generator's constants, and the kept deck against what the generator writes.
"""

import importlib.util
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "skfem_rkpm" / "runs" / "scenes" / "billet_3d.toml"


def generator():
    spec = importlib.util.spec_from_file_location(
        "calculix_billet", ROOT / "benchmarks" / "calculix" / "billet_3d.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_deck_constants_are_the_scene():
    ccx = generator()
    scene = tomllib.loads(SCENE.read_text())
    geometry, material = scene["geometry"], scene["material"]
    platen = scene["tools"]["platen"]
    assert ccx.SIZE == (geometry["lx"], geometry["ly"], geometry["lz"])
    assert (ccx.E, ccx.NU, ccx.YIELD) == (material["E"], material["nu"], material["yield"])
    assert material["hardening"] == "perfect"
    assert ccx.MU == platen["friction"]
    assert platen["motion"] == [0.0, 0.0, -ccx.PRESS]
    assert ccx.STEPS == scene["steps"]["count"]


def test_kept_deck_is_what_the_generator_writes():
    ccx = generator()
    kept = ROOT / "benchmarks" / "calculix" / "billet_3d_C3D20R_8x4x6.inp"
    assert kept.read_text() == ccx.deck("C3D20R", [8, 4, 6], 1e6, 1e5)


def test_quadratic_grid_has_the_twenty_node_count():
    """A structured 20-node brick mesh of n_x n_y n_z cells has corner nodes
    (n+1)^3 plus one node per edge."""
    ccx = generator()
    n = np.array([3, 2, 4])
    _, xyz = ccx.grid_nodes(list(n), quadratic=True)
    corners = np.prod(n + 1)
    edges = sum(n[a] * np.prod(np.delete(n + 1, a)) for a in range(3))
    assert len(xyz) == corners + edges
    cells = ccx.brick_connectivity(ccx.grid_nodes(list(n), True)[0], list(n), True)
    assert cells.shape == (np.prod(n), 20) and cells.min() >= 1
    # every cell's 20 nodes are distinct and its edge nodes are edge midpoints
    assert all(len(set(c)) == 20 for c in cells)
    mid = xyz[cells[:, 8] - 1]
    assert np.allclose(mid, 0.5 * (xyz[cells[:, 0] - 1] + xyz[cells[:, 1] - 1]))
