"""Any scikit-fem form on RK bases at the speed of :class:`~skfem_rkpm.Assembler`.

scikit-fem assembles a ``BilinearForm`` by calling it once per pair of local
functions; an RK cell has 30-300 of them.  But a bilinear form is linear in
the value and gradient components of ``u`` and of ``v``: at every point,

    form(u, v, w) = Σ_(c,i) Σ_(d,j) v_(c,i) D_(c,i),(d,j)(x) u_(d,j),

with ``u_(d,0)`` the value of component ``d`` and ``u_(d,j)`` its derivative
``∂_j``.  Calling the form once per pair of unit component fields (one
channel 1, the others 0, at every point) reads off its pointwise operator
``D`` exactly: ``(c (1 + dim))²`` calls instead of one per pair of local
functions.  :class:`~skfem_rkpm.Assembler` then integrates
``Σ ψ_(c,i) D φ_(d,j)`` with batched matrix products, with the values
stacked on the gradients as extra rows, and scatters into a cached pattern.
A ``LinearForm`` is read the same way, with ``c (1 + dim)`` calls.

:func:`asm` has the signature of ``skfem.asm``: bases are given trial first,
lists of bases are summed, ``to=`` receives scikit-fem ``COOData``, keyword
arguments become ``w`` (coefficient vectors are interpolated by the trial
basis, as in scikit-fem).  Forms on scikit-fem bases only go to
``skfem.asm`` unchanged.  An RK basis with a form that is not bilinear
(linear) in the value and gradient of ``u`` and ``v`` (checked with one
extra call on random combinations of the unit fields), a complex form, a
trilinear form, or a scikit-fem partner basis whose fields carry more than
values and gradients (``hess``, ``div``, composite elements) falls back to
scikit-fem's loop with a :class:`SlowAssemblyWarning` that says why.  A VCI
basis given as the trial basis of a form that reads trial gradients (where
``basis.trial`` was meant) gets a :class:`CorrectedTrialWarning`.

This module knows bases only by their attributes: an RK basis is one with
``element_nodes`` (see :func:`skfem_rkpm.assembly.layout`).
"""

import warnings
import weakref
from itertools import product

import numpy as np
import scipy.sparse as sp
from skfem import asm as skfem_asm
from skfem.assembly.form import BilinearForm, Form, Functional, LinearForm
from skfem.assembly.form.coo_data import COOData
from skfem.assembly.form.form import FormExtraParams
from skfem.element import DiscreteField, ElementVector

from .assembly import Assembler, Layout, layout
from .material_interfaces import check_interfaces

__all__ = ["asm", "check_fields", "check_quadrature", "pointwise_operator", "SlowAssemblyWarning",
           "PairwiseLoopWarning", "pairwise_loop_message", "scikit_fem_caller",
           "CorrectedTrialWarning"]

#: relative tolerance of the check that a form is (bi)linear in its arguments
LINEARITY_RTOL = 1e-9


class SlowAssemblyWarning(UserWarning):
    """A form on an RK basis is assembled by scikit-fem's loop over pairs of
    local functions (correct, 100-1000 times slower)."""


class PairwiseLoopWarning(SlowAssemblyWarning):
    """scikit-fem's own loop (``form.assemble(basis)``, ``skfem.asm``) read
    the local functions of an RK basis (:func:`pairwise_loop_message`)."""


#: the replacement of each scikit-fem call that runs its loop over local
#: functions, as :func:`pairwise_loop_message` names it
FAST_CALLS = {
    "skfem.asm": "from skfem_rkpm import asm (skfem.asm's signature: asm(form, basis), "
                 "asm(form, ubasis, vbasis), lists, to=, keyword fields)",
    "form.assemble": "skfem_rkpm.asm(form, basis, **kwargs) in place of "
                     "form.assemble(basis, **kwargs) (and skfem_rkpm.asm(form, ubasis, "
                     "vbasis) for form.assemble(ubasis, vbasis)): a method call does not "
                     "reach the asm imported from skfem_rkpm",
}


def scikit_fem_caller(depth=2):
    """Which scikit-fem call the current loop runs under, ``"skfem.asm"``
    or ``"form.assemble"`` (``Form.assemble``, ``elemental``, ``coo_data``),
    and the ``stacklevel`` of its caller counted from the caller of this
    function; ``(None, 2)`` if no scikit-fem frame is found."""
    import sys

    frame, level, call, user = sys._getframe(depth), 1, None, None
    seen = False
    while frame is not None:
        path = frame.f_code.co_filename.replace("\\", "/")
        inside = "/skfem/" in path and "/skfem_rkpm/" not in path
        if inside:
            seen = True
            name = frame.f_code.co_name
            if name == "asm" and path.endswith("assembly/__init__.py"):
                call = "skfem.asm"
            elif name in ("assemble", "elemental", "coo_data") and "/form/" in path \
                    and call != "skfem.asm":
                call = "form.assemble"
        elif seen:
            user = level
            break
        frame, level = frame.f_back, level + 1
    return call, (user + 1 if user is not None else 2)


def pairwise_loop_message(basis, call=None):
    """What scikit-fem's loop over local functions does on the RK ``basis``
    and the call that does it right and fast: for ``call`` (``"skfem.asm"``
    or ``"form.assemble"``, :data:`FAST_CALLS`) that call's replacement."""
    if call in FAST_CALLS:
        text = (f"{call} runs scikit-fem's loop over pairs of local functions, which on "
                "an RK basis is 100-1000 times slower than skfem_rkpm.asm; use "
                f"{FAST_CALLS[call]}")
    else:
        text = ("scikit-fem's loop over local functions (form.assemble(basis), skfem.asm) "
                "reads RKBasis.basis: on an RK basis it is 100-1000 times slower than "
                "skfem_rkpm.asm, which has skfem.asm's signature: "
                f"{FAST_CALLS['skfem.asm']}; {FAST_CALLS['form.assemble']}")
    text += ("; for a composite basis rk * fem, assemble its blocks with skfem_rkpm.asm "
             "and join them with scipy.sparse.bmat")
    if getattr(basis, "trial", basis) is not basis:
        text += (". With integration='vci' the local functions carry the corrected "
                 "*test* gradients; a bilinear form that reads trial gradients gets them "
                 "on the trial side too, which is not the consistent matrix (the patch "
                 "test fails): assemble with skfem_rkpm.asm(form, basis.trial, basis), "
                 "or build RKBasis(..., integration='vci_symmetric')")
    return text


class CorrectedTrialWarning(UserWarning):
    """The trial basis of a bilinear form carries VCI-corrected *test*
    gradients: the matrix is not the consistent Petrov-Galerkin one and the
    patch test fails."""


def _is_rk(basis):
    return hasattr(basis, "element_nodes")


def _as_form(form):
    """Wrap a plain function as skfem.asm does, by its number of arguments."""
    if not isinstance(form, Form) and callable(form):
        nargs = form.__code__.co_argcount
        form = [Functional, LinearForm, BilinearForm][nargs - 1](form)
    return form


def asm(form, *args, to=None, **kwargs):
    """Assemble a scikit-fem form; a drop-in for ``skfem.asm``.

    Parameters
    ----------
    form : BilinearForm, LinearForm, Functional or function
        The form (a plain function is wrapped by its number of arguments).
    *args : basis or list of bases
        Trial basis, then test basis (bilinear forms); lists are assembled
        for every combination and summed, as in ``skfem.asm``.
    to : callable, optional
        Receives the iterable of scikit-fem ``COOData`` of the combinations
        (as in ``skfem.asm``); default: their sum as a CSR matrix, vector or
        number.
    **kwargs
        Extra arguments of the form (``w``): numbers, ``DiscreteField`` or
        coefficient vectors (interpolated by the first basis).

    Returns
    -------
    scipy.sparse.csr_matrix, ndarray or float
        Like ``skfem.asm``.  Matrices assembled on RK bases keep structural
        zeros (scikit-fem drops them).
    """
    form = _as_form(form)
    lists = [a if isinstance(a, list) else [a] for a in args]
    if not any(_is_rk(b) for bases in lists for b in bases):
        return skfem_asm(form, *args, **({} if to is None else {"to": to}), **kwargs)
    parts = []
    for idx, bases in zip(product(*(range(len(x)) for x in lists)), product(*lists)):
        parts.append(assemble(form, *bases, idx=idx, **kwargs))  # warnings: stacklevel 4
    if to is not None:
        return to(iter([_coo(part) for part in parts]))
    return sum(parts[1:], parts[0])


def _coo(result):
    """A result of :func:`assemble` as scikit-fem's ``COOData``."""
    if sp.issparse(result):
        A = result.tocoo()
        return COOData(np.array([A.row, A.col]), A.data, A.shape, None)
    result = np.asarray(result)
    if result.ndim == 1:
        return COOData(np.arange(len(result))[None], result, result.shape, None)
    return COOData(np.array([]), np.array([result]), (), ())


def assemble(form, ubasis, vbasis=None, **kwargs):
    """One form on one trial (and test) basis; see :func:`asm`."""
    form = _as_form(form)
    check_fields(ubasis, kwargs)
    if _is_rk(ubasis):
        check_interfaces(isinstance(form, BilinearForm), ubasis, kwargs)
    if isinstance(form, BilinearForm):
        vbasis = ubasis if vbasis is None else vbasis
        check_quadrature(ubasis, vbasis)
        reason = _why_slow(form, ubasis, vbasis)
        if reason is None:
            result = _bilinear(form, ubasis, vbasis, kwargs)
            if not isinstance(result, str):
                return result
            reason = result
        _warn_slow(reason, ubasis, vbasis)
        return _pairwise_loop(form, ubasis, vbasis, **kwargs)
    if isinstance(form, LinearForm):
        if vbasis is not None:
            raise ValueError("a LinearForm takes one basis")
        reason = _why_slow(form, ubasis)
        if reason is None:
            result = _linear(form, ubasis, kwargs)
            if not isinstance(result, str):
                return result
            reason = result
        _warn_slow(reason, ubasis)
        return _pairwise_loop(form, ubasis, **kwargs)
    if isinstance(form, Functional):  # one call of the form: nothing to gain
        return form.assemble(ubasis, **kwargs)
    if any(_is_rk(b) for b in (ubasis, vbasis)):
        _warn_slow(f"{type(form).__name__} has no fast path", ubasis, vbasis)
    return _pairwise_loop(form, ubasis, *(() if vbasis is None else (vbasis,)), **kwargs)


def _pairwise_loop(form, *bases, **kwargs):
    """scikit-fem's own loop, once :func:`_warn_slow` has said why (the
    warning of ``RKBasis.basis`` would only repeat it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PairwiseLoopWarning)
        return form.assemble(*bases, **kwargs)


def _warn_slow(reason, *bases):
    if any(_is_rk(b) for b in bases if b is not None):
        warnings.warn(f"assembled with scikit-fem's loop over pairs of local functions "
                      f"(slow on RK bases): {reason}", SlowAssemblyWarning, stacklevel=4)


def check_fields(basis, fields):
    """Refuse ``DiscreteField`` arguments (``w``) not at the points of ``basis``.

    A field interpolated by an FEM basis with scikit-fem's default quadrature
    (3 points per P1 triangle) next to an RK basis (6): the message names
    ``rk.with_element(elem).interpolate(x)``, which evaluates it at the RK
    basis's points.
    """
    where = (basis.nelems, basis.X.shape[-1])
    for name, field in fields.items():
        if isinstance(field, DiscreteField) and np.shape(field)[-2:] != where:
            raise ValueError(
                f"Quadrature mismatch: {name!r} is given at {np.shape(field)[-2]} "
                f"cells x {np.shape(field)[-1]} points, the basis has "
                f"{where[0]} x {where[1]}; interpolate it at the basis's points, e.g. "
                f"basis.with_element(elem).interpolate(x) for FEM dofs x")


def check_quadrature(ubasis, vbasis):
    """Refuse a trial and a test basis on different cells or quadrature points.

    scikit-fem compares only the number of points per cell; an RK basis
    (``intorder=4`` by default) next to an FEM basis with its own default
    (``2 * maxdeg``: 3 points per triangle for P1, where the RK basis has 6)
    fails there, and two rules with equally many points would pass unseen.
    The message names the fix: ``rk.with_element(elem)`` (an FEM basis on the
    RK basis's quadrature) or ``Basis(mesh, elem, intorder=rk.intorder)``.
    """
    if ubasis is vbasis:
        return
    nqp = [b.X.shape[-1] for b in (ubasis, vbasis)]
    nelems = [b.nelems for b in (ubasis, vbasis)]
    same = nqp[0] == nqp[1] and nelems[0] == nelems[1] and np.allclose(
        ubasis.X, vbasis.X, rtol=0.0, atol=1e-12) and np.allclose(
        np.asarray(ubasis.dx), np.asarray(vbasis.dx), rtol=1e-10, atol=0.0)
    if same:
        return
    rk = next((b for b in (ubasis, vbasis) if _is_rk(b)), None)
    fix = "build both bases with the same quadrature=(X, W) and elements="
    if rk is not None and getattr(rk, "nodal_quadrature", None) is not None:
        fix = (f"the RK basis integrates at its particles (integration="
               f"{rk.integration!r}); mixed RK x FEM forms need a cell scheme "
               "(integration='vci', 'vci_symmetric' or 'gauss') and rk.with_element(elem)")
    elif rk is not None:
        fix = (f"take the FEM basis from the RK basis, rk.with_element(elem) (same "
               f"cells and points), or build it as Basis(mesh, elem, "
               f"intorder={rk.intorder}) (the RK basis's intorder)"
               + ("" if rk.tind is None else " with the same elements="))
    raise ValueError(
        f"Quadrature mismatch: the trial basis has {nelems[0]} cells x {nqp[0]} "
        f"quadrature points, the test basis {nelems[1]} x {nqp[1]}"
        + (" at other points" if nqp[0] == nqp[1] and nelems[0] == nelems[1] else "")
        + f"; {fix}")


def _why_slow(form, *bases):
    """Why ``form`` on ``bases`` cannot take the fast path, or None."""
    if np.dtype(form.dtype) != np.float64:
        return f"the form has dtype {np.dtype(form.dtype)} (the fast path is real)"
    if not any(_is_rk(b) for b in bases):
        return "no RK basis"
    for b in bases:
        if not _is_rk(b):
            fields = b.basis[0]
            extra = [a for a in DiscreteField._extra_attrs[1:]
                     if getattr(fields[0], a) is not None]
            if len(fields) != 1 or extra:
                return (f"the scikit-fem basis of {type(b.elem).__name__} has "
                        + ("several fields" if len(fields) != 1 else
                           "fields with " + ", ".join(extra)))
            try:
                layout(b)
            except ValueError as err:
                return str(err)
    return None


# -- channels: value and gradient components as rows of one table ----------

def _unit_fields(ncomp, dim, shape):
    """Unit fields of one basis: per channel ``(c, i)`` a ``DiscreteField`` whose
    component ``c`` has value 1 (``i = 0``) or derivative ``∂_(i-1)`` 1 and
    all else zero, on points of ``shape`` (nelems, nqp).  The arrays are
    read-only broadcast views: they take no memory per point."""
    lead = (ncomp,) if ncomp > 1 else ()
    ones = (1,) * len(shape)
    fields = []
    for c in range(ncomp):
        for i in range(1 + dim):
            value = np.zeros(lead + ones)
            grad = np.zeros(lead + (dim,) + ones)
            if i == 0:
                value[(c,) * len(lead)] = 1.0
            else:
                grad[(c,) * len(lead) + (i - 1,)] = 1.0
            fields.append(DiscreteField(np.broadcast_to(value, lead + shape),
                                        np.broadcast_to(grad, lead + (dim,) + shape)))
    return fields


def _combination(fields, coefficients):
    """Σ coefficients[k] fields[k] as a ``DiscreteField``."""
    value = sum(a * np.asarray(f) for a, f in zip(coefficients, fields))
    grad = sum(a * f.grad for a, f in zip(coefficients, fields))
    return DiscreteField(value, grad)


def _ncomp(basis):
    if _is_rk(basis):
        return basis.ncomp
    return basis.elem.dim if isinstance(basis.elem, ElementVector) else 1


def pointwise_operator(form, ubasis, vbasis=None, w=None):
    """The pointwise operator ``D`` of a bilinear form (see the module docstring).

    Parameters
    ----------
    form : BilinearForm
    ubasis, vbasis : basis
        Trial and test bases (``vbasis`` default ``ubasis``).
    w : FormExtraParams, optional
        The form's extra arguments; default the trial basis's parameters.

    Returns
    -------
    ndarray, shape (c_v, 1 + dim, c_u, 1 + dim, nelems, nqp)
        ``D[c, i, d, j]`` multiplies channel ``i`` of test component ``c``
        (0: value, 1 + l: ``∂_l``) and channel ``j`` of trial component ``d``.
    """
    vbasis = ubasis if vbasis is None else vbasis
    if w is None:
        w = FormExtraParams(ubasis.default_parameters())
    D = _operator(form, ubasis, vbasis, w)
    k = 1 + ubasis.mesh.dim()
    full = D.dense()
    if full.ndim == 2:  # the same at every point
        full = np.broadcast_to(full[..., None, None], full.shape + D.shape).copy()
    return full.reshape(_ncomp(vbasis), k, _ncomp(ubasis), k, *D.shape)


class _Operator:
    """A pointwise operator kept compactly: ``constant`` (test channels x trial
    channels) holds the entries that are the same at every point (zero
    included), ``varying`` the others as arrays (nelems, nqp) by entry.
    ``U``, ``V``: the unit fields of the trial and test basis."""

    def __init__(self, constant, varying, shape, U, V):
        self.constant, self.varying, self.shape = constant, varying, shape
        self.U, self.V = U, V

    def nonzero(self):
        """Entries not identically zero, (test channels, trial channels)."""
        out = self.constant != 0
        for a, b in self.varying:
            out[a, b] = True
        return out

    def dense(self, rows=None, cols=None):
        """The entries of ``rows`` x ``cols`` (default all) at every point,
        or at one point if none of them varies."""
        rows = np.arange(self.constant.shape[0]) if rows is None else rows
        cols = np.arange(self.constant.shape[1]) if cols is None else cols
        constant = self.constant[np.ix_(rows, cols)]
        in_rows, in_cols = set(rows.tolist()), set(cols.tolist())
        where = {(a, b): v for (a, b), v in self.varying.items()
                 if a in in_rows and b in in_cols}
        if not where:
            return constant
        out = np.empty(constant.shape + self.shape)
        out[...] = constant[..., None, None]
        row_of = {a: n for n, a in enumerate(rows)}
        col_of = {b: n for n, b in enumerate(cols)}
        for (a, b), v in where.items():
            out[row_of[a], col_of[b]] = v
        return out

    def contracted(self, s, r):
        """``Σ_ab s_a D_ab r_b`` and the same sum of absolute values, per point."""
        value = np.full(self.shape, s @ self.constant @ r)
        bound = np.full(self.shape, np.abs(s) @ np.abs(self.constant) @ np.abs(r))
        for (a, b), v in self.varying.items():
            value += s[a] * r[b] * v
            bound += abs(s[a] * r[b]) * np.abs(v)
        return value, bound


def _operator(form, ubasis, vbasis, w):
    """The pointwise operator of ``form``, compactly (:class:`_Operator`): one
    call of the form per pair of unit fields, only varying entries stored."""
    shape = ubasis.dx.shape
    dim = ubasis.mesh.dim()
    U, V = _unit_fields(_ncomp(ubasis), dim, shape), _unit_fields(_ncomp(vbasis), dim, shape)
    constant = np.zeros((len(V), len(U)))
    varying = {}
    for (b, u), (a, v) in product(enumerate(U), enumerate(V)):
        value = _per_point(form.form(u, v, w), shape)
        first = value.flat[0]
        if np.all(value == first):
            constant[a, b] = first
        else:
            varying[a, b] = np.array(value, dtype=float)
    return _Operator(constant, varying, shape, U, V)


class _NotPerPoint(ValueError):
    """A form's value is not one number per quadrature point."""


def _per_point(value, shape):
    """``value`` as one number per quadrature point, shape (nelems, nqp)."""
    value = np.asarray(value)
    if value.shape != shape and value.ndim != 0:
        raise _NotPerPoint(
            f"the form returns an array of shape {value.shape}, not one number per "
            f"quadrature point {shape} (a vector or a sum over cells: e.g. dot() of "
            "two scalar fields contracts the cells)")
    return np.broadcast_to(value, shape)


def _agrees(direct, D, coefficients):
    """``direct`` (a call on combinations of unit fields with ``coefficients``,
    test first) equals ``D`` (test channels x trial channels x points)
    contracted with them, up to ``LINEARITY_RTOL`` of the largest term."""
    expected, bound = D, np.abs(D)
    for r in coefficients:  # contract the leading channel axis
        expected = np.tensordot(r, expected, axes=(0, 0))
        bound = np.tensordot(np.abs(r), bound, axes=(0, 0))
    return np.all(np.abs(np.asarray(direct) - expected)
                  <= LINEARITY_RTOL * bound.max(initial=0.0))


def _random_combinations(fields, rng):
    coefficients = rng.uniform(0.5, 1.5, len(fields))
    return _combination(fields, coefficients), coefficients


def _bilinear(form, ubasis, vbasis, kwargs):
    """The fast path of a bilinear form, or the reason it cannot be taken."""
    w = FormExtraParams({**ubasis.default_parameters(),
                         **form._normalize_asm_kwargs(dict(kwargs), ubasis)})
    try:
        D = _operator(form, ubasis, vbasis, w)
    except _NotPerPoint as err:
        return str(err)
    rng = np.random.default_rng(0)
    (u, r), (v, s) = _random_combinations(D.U, rng), _random_combinations(D.V, rng)
    expected, bound = D.contracted(s, r)
    if not np.all(np.abs(np.asarray(form.form(u, v, w)) - expected)
                  <= LINEARITY_RTOL * bound.max(initial=0.0)):
        return "the form is not bilinear in the values and gradients of u and v"
    k = 1 + ubasis.mesh.dim()
    cv, cu = _ncomp(vbasis), _ncomp(ubasis)
    nonzero = D.nonzero().reshape(cv, k, cu, k)
    i = np.flatnonzero(nonzero.any(axis=(0, 2, 3)))
    j = np.flatnonzero(nonzero.any(axis=(0, 1, 2)))
    if len(i) == 0 or len(j) == 0:
        return sp.csr_matrix((vbasis.N, ubasis.N))
    if np.any(j > 0) and _is_rk(ubasis) and getattr(ubasis, "trial", ubasis) is not ubasis:
        warnings.warn(
            "the trial basis carries the VCI-corrected test gradients (integration="
            f"{getattr(ubasis, 'integration', 'vci')!r}) and the form uses trial "
            "gradients: the matrix is not the consistent one and fails the patch test; "
            "pass basis.trial as trial basis, asm(form, basis.trial, basis), or build "
            "the basis with integration='vci_symmetric'", CorrectedTrialWarning,
            stacklevel=4)
    rows = (np.arange(cv)[:, None] * k + i[None, :]).ravel()
    cols = (np.arange(cu)[:, None] * k + j[None, :]).ravel()
    C = D.dense(rows, cols)
    C = C.reshape((cv, len(i), cu, len(j)) + C.shape[2:])
    pattern, Lu, Lv = _cached_pattern(ubasis, vbasis)
    # one assembler per set of channels, kept with the pattern: it keeps its
    # tables in the layouts of the batched products between calls
    by_channels = pattern.__dict__.setdefault("_by_channels", {})
    assembler = by_channels.get((tuple(i), tuple(j)))
    if assembler is None:
        trial = _channel_layout(Lu, j, ubasis.dx)
        test = trial if vbasis is ubasis and np.array_equal(i, j) else \
            _channel_layout(Lv, i, ubasis.dx)
        assembler = by_channels[tuple(i), tuple(j)] = pattern.with_layouts(trial, test)
    return assembler.bilinear(C)


def _channel_layout(L, kept, dx):
    """``L`` with the kept channels (0: values, 1 + l: ``∂_l``, the gradients
    its forms see) as the rows of its gradient table."""
    dim = L.test_grads.shape[0]
    if np.array_equal(kept, np.arange(1, 1 + dim)):
        table = L.test_grads  # gradients only: no copy
    elif np.array_equal(kept, [0]):
        table = L.values[None]
    else:
        table = np.concatenate([L.values[None], L.test_grads])[kept]
    return Layout(L.element_nodes, L.values, table, table, dx, L.ncomp, L.nscalar)


def _linear(form, vbasis, kwargs):
    """The fast path of a linear form, or the reason it cannot be taken."""
    w = FormExtraParams({**vbasis.default_parameters(),
                         **form._normalize_asm_kwargs(dict(kwargs), vbasis)})
    shape = vbasis.dx.shape
    dim, cv = vbasis.mesh.dim(), _ncomp(vbasis)
    V = _unit_fields(cv, dim, shape)
    D = np.empty((len(V),) + shape)
    try:
        for a, v in enumerate(V):
            D[a] = _per_point(form.form(v, w), shape)
    except _NotPerPoint as err:
        return str(err)
    v, s = _random_combinations(V, np.random.default_rng(0))
    if not _agrees(form.form(v, w), D, (s,)):
        return "the form is not linear in the values and gradients of v"
    D = D.reshape(cv, 1 + dim, *shape)
    i = np.flatnonzero(np.any(D != 0, axis=(0, 2, 3)))  # channels in use
    if len(i) == 0:
        return np.zeros(vbasis.N)
    test = _channel_layout(layout(vbasis), i, vbasis.dx)
    assembler = Assembler(test, pattern=False)  # vectors need no sparsity pattern
    return assembler.linear(D[:, i])


# -- sparsity patterns, kept while the bases live ---------------------------

_PATTERNS = weakref.WeakKeyDictionary()


def _cached_pattern(ubasis, vbasis):
    """``(assembler, trial layout, test layout)`` of the pair, built once and
    kept on the test basis for as long as both bases live."""
    cache = _PATTERNS.setdefault(vbasis, {})
    for key in [k for k, e in cache.items() if e[0]() is None]:
        del cache[key]  # trial bases that are gone: free their tables
    entry = cache.get(id(ubasis))
    if entry is None or entry[0]() is not ubasis:
        Lu = layout(ubasis)
        Lv = layout(vbasis) if vbasis is not ubasis else Lu
        same = Lu.element_nodes is Lv.element_nodes and Lu.ncomp == Lv.ncomp
        assembler = Assembler(Lu) if same else Assembler(Lu, test=Lv)
        entry = cache[id(ubasis)] = (weakref.ref(ubasis), assembler, Lu, Lv)
    return entry[1:]
