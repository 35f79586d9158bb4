"""Dof numbers of RK bases that also answer scikit-fem's ``DofsView`` calls.

scikit-fem code writes ``basis.get_dofs("left").all()``,
``.nodal["u^1"]``, ``.all("u^2")``, ``.keep([...])`` or ``.drop([...])``;
an RK basis has one dof per particle and component (interleaved
``ncomp*I + c``), named like scikit-fem's ``ElementVector`` dofs: ``"u"``
for a scalar field, ``"u^1"``, ``"u^2"``, ... for the components of a
vector field.  Particles carry all dofs: ``facet``, ``edge`` and
``interior`` are empty.  :class:`RKDofs` is a sorted integer array as
well, so array code (``x[D]``, ``np.setdiff1d``, ``skfem_rkpm.solve``)
keeps working.
"""

import numpy as np

__all__ = ["RKDofs"]


class RKDofs(np.ndarray):
    """Sorted dof numbers of an RK basis with scikit-fem's ``DofsView`` methods.

    Parameters
    ----------
    dofs : array of int
        Sorted dof numbers ``ncomp*I + c``.
    ncomp : int
        Components of the basis.
    """

    def __new__(cls, dofs, ncomp):
        obj = np.asarray(dofs, dtype=np.int64).view(cls)
        obj.ncomp = int(ncomp)
        return obj

    def __array_finalize__(self, obj):
        self.ncomp = getattr(obj, "ncomp", 1)

    def __array_wrap__(self, out_arr, context=None, return_scalar=False):
        # arithmetic on dof numbers gives plain arrays, not dof sets
        return np.asarray(out_arr)[()] if return_scalar else np.asarray(out_arr)

    @property
    def names(self):
        """Dof names of the basis: ``["u"]`` or ``["u^1", ..., "u^ncomp"]``."""
        if self.ncomp == 1:
            return ["u"]
        return [f"u^{c + 1}" for c in range(self.ncomp)]

    def _component(self, name):
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"no dofs named {name!r}: an RK basis with {self.ncomp} "
                             f"component(s) has {self.names}") from None

    def _select(self, names):
        names = [names] if isinstance(names, str) else list(names)
        return {self._component(n) for n in names}

    @property
    def nodal(self):
        """``{name: dof numbers}`` per component, as scikit-fem's ``DofsView.nodal``."""
        plain = np.asarray(self)
        return {name: plain[plain % self.ncomp == c] for c, name in enumerate(self.names)}

    @property
    def facet(self):
        """Empty: RK dofs all belong to particles."""
        return {}

    edge = interior = facet

    def keep(self, names):
        """The dofs of the components named ``names`` (e.g. ``"u^1"``)."""
        keep = self._select(names)
        plain = np.asarray(self)
        return RKDofs(plain[np.isin(plain % self.ncomp, list(keep))], self.ncomp)

    def drop(self, names):
        """The dofs of all components but those named ``names``."""
        drop = self._select(names)
        return self.keep([n for c, n in enumerate(self.names) if c not in drop])

    def all(self, key=None, **reduction):
        """A plain sorted array of the dofs (of components ``key`` if given).

        With numpy's reduction arguments (``np.all(D)`` passes ``axis`` and
        the like) this is ``ndarray.all``.
        """
        if reduction:
            return np.asarray(self).all(**reduction)
        return np.array(self if key is None else self.keep(key))

    def flatten(self, order="C"):
        """A plain array of the dofs, as ``DofsView.flatten``."""
        return np.array(self).flatten(order)
