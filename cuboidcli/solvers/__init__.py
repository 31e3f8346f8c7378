"""Cuboid solvers: minimal sets of points -> cuboid hypotheses (paper Sec. 3.2.2 and 3.2.3)."""
