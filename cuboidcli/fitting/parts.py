"""The samplers and solvers a fit can name: one line each in :data:`PARTS`.

``FitConfig.sampler`` and ``FitConfig.solver`` take these names. Everything that knows the names reads them
here: the settings' check (:meth:`~cuboidcli.fitting.config.FitConfig.check`), the factories that build a
part by name (:mod:`cuboidcli.factories`), the weights registry that knows which network a configuration
loads (:mod:`cuboidcli.weights`), the Python API and the command line (their choices and messages).

A part is built by its builder, named as ``"module:function"`` and imported only when the part is first
built: the estimator (this package) knows the parts by their protocols alone and imports none of them.
Every builder lives in the module of its part (``cuboidcli.solvers.numerical:build``), takes one
:class:`BuildInputs` and returns the sampler (:class:`cuboidcli.sampling.Sampler`) or the solver
(:class:`cuboidcli.solvers.base.CuboidSolver`). The part modules lie below this package, so a builder reads
its inputs by attribute and never imports them. Adding a part is its module, with such a builder, and its
line here.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: The roles of a part: the FitConfig field that names it.
ROLES = ("sampler", "solver")


@dataclass(frozen=True)
class BuildInputs:
    """What a builder gets. The factories resolve the weights file with the weights registry before they
    call it, so a part never looks weights up itself."""

    config: Any
    """The fit's settings, a :class:`~cuboidcli.fitting.config.FitConfig` (bounds, learning rate, backend,
    ...); not imported here because the config reads this registry."""
    weights: Path | None = None
    """The file of the part's network (:attr:`Part.network`); None for a part that loads none."""
    onnx: Path | None = None
    """The exported solver that ``--onnx`` names, for the ``onnx`` solver."""
    device: str = "cpu"
    """The torch device a network runs on."""


@dataclass(frozen=True)
class Part:
    role: str
    """``sampler`` or ``solver``."""
    name: str
    """What ``--sampler`` / ``--solver`` and FitConfig take."""
    builder: str
    """``"module:function"`` that builds it from :class:`BuildInputs`."""
    network: str | None
    """The kind of network it loads from ``--weights`` (``"sampler"``, ``"solver"``; a kind of
    :data:`cuboidcli.weights.NETWORKS`), or None when it loads none."""
    help: str
    """What it is, in one line."""

    @property
    def flag(self) -> str:
        """How the command line selects it: ``--solver neural``."""
        return f"--{self.role} {self.name}"

    def build(self, inputs: BuildInputs):
        """The sampler or solver, built by :attr:`builder` (imported now)."""
        module, _, function = self.builder.partition(":")
        return getattr(importlib.import_module(module), function)(inputs)


#: Every sampler and solver, in the order the command line lists them.
PARTS: tuple[Part, ...] = (
    Part("sampler", "sequential", "cuboidcli.sampling:build_sequential", None,
         "1 - max(state, 0), Sequential RANSAC: points already explained are drawn less"),
    Part("sampler", "learned", "cuboidcli.sampling.learned:build", "sampler",
         "the sampling-weight network, Sec. 3.2.1"),
    Part("sampler", "local", "cuboidcli.sampling:build_local", None,
         "sequential with every set localised"),
    Part("sampler", "uniform", "cuboidcli.sampling:build_uniform", None,
         "every valid point equally likely"),
    Part("solver", "numerical", "cuboidcli.solvers.numerical:build", None,
         "PCA + Adam"),
    Part("solver", "neural", "cuboidcli.solvers.neural:build", "solver",
         "the regression network"),
    Part("solver", "onnx", "cuboidcli.solvers.onnx:build", None,
         "the neural solver exported with ``cuboids export --onnx``"),
)  # fmt: skip


def names(role: str) -> tuple[str, ...]:
    """The names of the parts of ``role``, in :data:`PARTS` order."""
    return tuple(p.name for p in PARTS if p.role == role)


def describe(role: str) -> str:
    """Every part of ``role`` with its help, as the settings' documentation and ``--help`` list them:
    ```sequential`` (...), ``learned`` (...)``."""
    return ", ".join(f"``{p.name}`` ({p.help})" for p in PARTS if p.role == role)


def or_list(words) -> str:
    """``a, b or c``."""
    words = list(words)
    return f"{', '.join(words[:-1])} or {words[-1]}" if len(words) > 1 else "".join(words)


def find(role: str, name: str) -> Part:
    """The part of ``role`` called ``name``; a one-line ValueError for a name that is not registered."""
    for p in PARTS:
        if p.role == role and p.name == name:
            return p
    raise ValueError(f"unknown {role} {name!r}; choose {or_list(names(role))}")


def network_of(role: str, name: str) -> str | None:
    """The kind of network the part of ``role`` called ``name`` loads; None when it loads none or is not
    registered (the factories refuse that name)."""
    return next((p.network for p in PARTS if p.role == role and p.name == name), None)


def loading(kind: str) -> tuple[Part, ...]:
    """The parts that load a network of ``kind`` from ``--weights``."""
    return tuple(p for p in PARTS if p.network == kind)


#: The names each role takes, in :data:`PARTS` order.
SAMPLERS = names("sampler")
SOLVERS = names("solver")
