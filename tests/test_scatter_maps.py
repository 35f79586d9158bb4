"""The scatter maps of :class:`skfem_rkpm.assembly.Assembler`: every way of
finding the places of the local entries (stored intp map, stored int32 map,
dense table looked up per block, binary search) sums the same matrix, equal
to an independent COO assembly of the local matrices, over repeated calls."""

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementHex1, ElementQuad1, ElementVector, MeshHex, MeshQuad

from skfem_rkpm import Assembler, RKBasis, assembly, isotropic_tangent

MODES = {  # (DENSE_POSITIONS, STORED_ENTRIES, COMPACT_ENTRIES)
    "stored intp": (2**24, 2**40, 2**40),
    "stored int32": (2**24, 0, 2**40),
    "table per block": (2**24, 0, 0),
    "binary search": (0, 0, 0),
}


def use_mode(monkeypatch, mode, scatter_entries=None):
    """Make new assemblers find their places the way ``mode`` of :data:`MODES`
    says (and sum ``scatter_entries`` local entries per block if given)."""
    for name, value in zip(("DENSE_POSITIONS", "STORED_ENTRIES", "COMPACT_ENTRIES"),
                           MODES[mode]):
        monkeypatch.setattr(assembly, name, value)
    if scatter_entries is not None:
        monkeypatch.setattr(assembly, "SCATTER_ENTRIES", scatter_entries)


def coo_reference(A, local):
    """The local matrices (nelems, nloc, c, c, nloc) summed by scipy's COO
    conversion, rows and columns from the element dofs."""
    L = A.layout
    c, (nloc, nelems) = L.ncomp, L.element_nodes.shape
    dofs = (c * L.element_nodes.T[:, :, None] + np.arange(c)).reshape(nelems, -1)
    rows = np.broadcast_to(dofs[:, :, None], (nelems, nloc * c, nloc * c))
    # local[e, a, c_a, c_b, b] is the entry (row dof (a, c_a), column dof (b, c_b))
    cols = np.broadcast_to(dofs.reshape(nelems, nloc, c).transpose(0, 2, 1)
                           .reshape(nelems, 1, -1), rows.shape)
    return sp.coo_matrix((local.ravel(), (rows.ravel(), cols.ravel())),
                         shape=A.shape).tocsr()


def bases():
    quads = MeshQuad.init_tensor(np.linspace(0, 1, 6), np.linspace(0, 0.6, 4))
    hexes = MeshHex.init_tensor(*(np.linspace(0, 1, n) for n in (4, 3, 3)))
    return {
        "RK 2D": RKBasis(quads, vector=True, support=2.0),
        "RK 3D": RKBasis(hexes, vector=True, support=2.0, intorder=2),
        "FEM Hex1": Basis(hexes, ElementVector(ElementHex1()), intorder=2),
        "FEM Quad1 scalar": Basis(quads, ElementQuad1(), intorder=2),
    }


@pytest.mark.parametrize("name", list(bases()))
def test_every_scatter_map_sums_the_coo_matrix(monkeypatch, name):
    basis = bases()[name]
    rng = np.random.default_rng(3)
    reference = Assembler(basis)
    L = reference.layout
    shape = (L.element_nodes.shape[1], L.element_nodes.shape[0], L.ncomp, L.ncomp,
             L.element_nodes.shape[0])
    locals_ = [rng.normal(size=shape) for _ in range(3)]
    expected = [coo_reference(reference, local) for local in locals_]
    for mode in MODES:
        use_mode(monkeypatch, mode, scatter_entries=997)  # several blocks
        A = Assembler(basis)
        kept = (A._pattern[0] is not None, A._compact is not None)
        assert kept == {"stored int32": (False, True), "table per block": (False, False)}.get(
            mode, (True, False)), mode  # binary search always stores the map
        for local, K_ref in zip(locals_ * 2, expected * 2):  # repeated calls
            K = A.matrix(local)
            assert K.has_sorted_indices
            # the same sums in another order: a few units of round-off of the
            # largest entry summed (at most nloc cells share a pair)
            scale = np.abs(local).max() * L.element_nodes.shape[0]
            assert abs(K - K_ref).max() <= 8 * np.finfo(float).eps * scale, mode
            assert K.nnz == A.nnz


@pytest.mark.parametrize("name", ["RK 3D", "FEM Hex1"])
def test_tangent_is_the_same_with_every_scatter_map(monkeypatch, name):
    """``bilinear`` (blocks summed as they are computed when no map is stored)
    gives the matrix of the stored map to round-off."""
    basis = bases()[name]
    C = isotropic_tangent(1.7, 0.9, 3)
    expected = Assembler(basis).bilinear(C)
    for mode, (dense, stored, compact) in MODES.items():
        monkeypatch.setattr(assembly, "DENSE_POSITIONS", dense)
        monkeypatch.setattr(assembly, "STORED_ENTRIES", stored)
        monkeypatch.setattr(assembly, "COMPACT_ENTRIES", compact)
        K = Assembler(basis).bilinear(C)
        assert abs(K - expected).max() <= 1e-13 * abs(expected).max(), mode


@pytest.mark.parametrize("name", ["RK 3D", "FEM Quad1 scalar"])
def test_streamed_local_matrices_sum_the_coo_matrix(monkeypatch, name):
    """``streamed`` (local matrices handed over block by block of cells, in
    cell order) sums the matrix of the COO reference with every scatter map,
    each block asked for once."""
    basis = bases()[name]
    rng = np.random.default_rng(5)
    L = Assembler(basis).layout
    nloc, nelems = L.element_nodes.shape
    local = rng.normal(size=(nelems, nloc, L.ncomp, L.ncomp, nloc))
    for mode in MODES:
        use_mode(monkeypatch, mode, scatter_entries=50)  # several blocks
        A = Assembler(basis)
        asked = []

        def local_of(s):
            asked.append((s.start, s.stop))
            return local[s]

        K = A.streamed(local_of, local[0].size)
        starts, stops = zip(*asked)
        assert starts[0] == 0 and stops[-1] == nelems and starts[1:] == stops[:-1], mode
        assert len(asked) > 1, mode
        scale = np.abs(local).max() * nloc
        assert abs(K - coo_reference(A, local)).max() <= 8 * np.finfo(float).eps * scale, mode
        assert K.nnz == A.nnz
