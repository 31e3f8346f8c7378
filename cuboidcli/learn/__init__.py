"""Learned components (paper Sec. 3.2.3 and 3.4): the neural cuboid solver and its synthetic pre-training."""
