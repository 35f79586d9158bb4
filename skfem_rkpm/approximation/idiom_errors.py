"""The errors of scikit-fem idioms an RK basis cannot honour as asked
(raised by :mod:`.basis_views`, :mod:`.basis_element` and the bases)."""

__all__ = ["BasisIdiomError", "CoefficientsNotNodalError"]


class BasisIdiomError(NotImplementedError):
    """A scikit-fem basis idiom an RK basis cannot honour as asked.

    The message names what to use instead.
    """


class CoefficientsNotNodalError(BasisIdiomError, AttributeError):
    """An idiom that would read RK coefficients as nodal values (``x[basis.nodal_dofs[0]]``).

    Also an ``AttributeError``: ``hasattr(basis, "nodal_dofs")`` is False.
    """
