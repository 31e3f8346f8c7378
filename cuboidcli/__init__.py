"""cuboids: robust cuboid abstraction of depth maps (Kluger et al., TPAMI 2024)."""

__version__ = "0.1.0"
