"""The robust multi-cuboid estimator (paper Sec. 3.2): sample -> solve -> score -> select, repeated."""
