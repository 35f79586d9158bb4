"""The RK functions: kernels, shape tables, quadrature and VCI, the basis, Λ.

Nothing here knows physics, solvers or scene files.
"""
