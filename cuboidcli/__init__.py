"""cuboids: robust cuboid abstraction of depth maps (Kluger et al., TPAMI 2024).

The Python API (:mod:`cuboidcli.api`), imported on first use so that ``import cuboidcli`` stays light::

    import cuboidcli as cb
    result = cb.fit(cb.read_depth("d.png"), cb.Camera(518.86, 519.47, 325.58, 253.74), seed=0)
"""

from __future__ import annotations

__version__ = "0.2.0"

#: Public name -> module that defines it.
_EXPORTS = {
    "Camera": "cuboidcli.camera",
    "Cuboid": "cuboidcli.cuboid",
    "FitConfig": "cuboidcli.fitting.config",
    "Fitter": "cuboidcli.api",
    "Result": "cuboidcli.result",
    "LoadOptions": "cuboidcli.load",
    "fit": "cuboidcli.api",
    "read_depth": "cuboidcli.api",
    "read_rgb": "cuboidcli.api",
    "read_camera": "cuboidcli.api",
    "estimate_depth": "cuboidcli.api",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cuboidcli' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
