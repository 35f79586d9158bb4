"""Newton's method with load stepping, linear solver backends, PETSc/MPI.

Knows the physics through ``SolidProblem``; knows no scene file.
"""
