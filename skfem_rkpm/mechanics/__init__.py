"""Finite-strain solid mechanics on any basis: kinematics, materials, problems."""
