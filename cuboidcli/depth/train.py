"""``python -m cuboidcli.depth.train DATA --out DIR [...]``: the older spelling of ``cuboids train depth DATA
--out DIR --json [...]`` (the same options; one JSON record a line on stdout).

The trainer is :mod:`cuboidcli.learn.depth_train`, the command line :mod:`cuboidcli.cli.train_depth`. This
entry point reaches the command line through :func:`importlib.import_module` when it runs: the depth package
sits below ``learn`` and ``cli`` in the import layers (``tests/test_layers.py``) and imports neither.
"""

from __future__ import annotations

import importlib


def main(argv: list[str] | None = None) -> None:
    """Run ``cuboids train depth ARGV --json`` (``argv`` None: the process's arguments)."""
    importlib.import_module("cuboidcli.cli.train_depth").module_main(argv)


if __name__ == "__main__":
    main()
