"""Neural cuboid solver (paper Sec. 3.2.3): one forward pass of the regression network per batch of sets.

Weights are plain dicts ``{"config", "state_dict", "meta"}`` loaded with ``torch.load(weights_only=True)``;
see :mod:`cuboidcli.nets.solver`. The solver takes a weights file or a loaded net; which file a
``--weights`` value names is decided by :func:`cuboidcli.factories.make_solver` with the weights registry
(:mod:`cuboidcli.weights`; the shipped weights live in ``models/`` beside their model card).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import torch
from torch import Tensor

from cuboidcli.io.checkpoints import load_net
from cuboidcli.nets.solver import SolverNet, net_from_checkpoint
from cuboidcli.solvers.base import SizeBounds

#: Sets per forward chunk on the CPU: 512 x 6 points keep the activations (~1 MB per layer) in the cache,
#: which made the 4096-set forward pass about 1.5x faster than one big batch.
CHUNK_SETS = 512


def load_solver_net(path: str | os.PathLike, device: str | torch.device = "cpu") -> SolverNet:
    """Load a solver checkpoint into an eval-mode float32 net on ``device``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"solver weights {path} not found; pass a .pt file written by 'cuboids train solver'"
        )
    net = load_net(path, "solver", net_from_checkpoint)
    return net.to(device=device, dtype=torch.float32).eval()


def check_bounds(bounds: SizeBounds | None, a_min: float, a_max: float) -> SizeBounds:
    """The solver's bounds: those the weights were trained for; a different request is an error."""
    trained = SizeBounds(a_min=a_min, a_max=a_max)
    if bounds is None:
        return trained
    if abs(bounds.a_min - a_min) > 1e-9 or abs(bounds.a_max - a_max) > 1e-9:
        raise ValueError(
            f"the solver weights were trained for half-sizes in [{a_min:g}, {a_max:g}] m but "
            f"[{bounds.a_min:g}, {bounds.a_max:g}] m was requested; use matching bounds or other weights"
        )
    return bounds


@contextmanager
def _intra_op_threads(n: int):
    """Temporarily set torch's intra-op thread count (a process-wide setting)."""
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


class NeuralSolver:
    """CuboidSolver backed by :class:`SolverNet`. ``minimal_sets`` (H, C, 3) m -> centers (H, 3),
    half_sizes (H, 3), rotations (H, 3, 3), in the input's dtype and device.

    Runs in eval mode under ``torch.inference_mode`` (no gradients): fine-tuning uses ``self.net`` directly.

    On the CPU the sets are split into ``threads`` parts (default: torch's thread count) that run in a
    thread pool, each single-threaded in cache-sized chunks. Why not torch's own intra-op threads: with a
    few dozen small ops per chunk, every op is a barrier between the threads, and on a busy machine each
    barrier waits for a time slice; 4096 sets then took seconds instead of ~0.1 s. One coarse split is
    immune to that. torch's thread setting is set to 1 for the duration of a call and then restored.
    """

    name = "neural"

    def __init__(
        self,
        weights: str | os.PathLike | None = None,
        device: str | torch.device = "cpu",
        bounds: SizeBounds | None = None,
        net: SolverNet | None = None,
        threads: int | None = None,
    ) -> None:
        if net is None and weights is None:
            raise TypeError("NeuralSolver needs a weights file or a loaded net")
        self.device = torch.device(device)
        self.net = net.to(self.device).eval() if net is not None else load_solver_net(weights, self.device)
        cfg = self.net.config
        self.bounds = check_bounds(bounds, cfg.a_min, cfg.a_max)
        self.threads = threads
        self._pool: ThreadPoolExecutor | None = None
        self._pool_size = 0

    def _forward(self, x: Tensor, chunk: int) -> tuple[Tensor, Tensor, Tensor]:
        # inference_mode is thread-local, so it is entered here, in whichever thread runs the part.
        with torch.inference_mode():
            parts = [self.net(c) for c in x.split(chunk)] or [self.net(x)]
            return tuple(torch.cat(p) for p in zip(*parts, strict=True))

    def _forward_parallel(self, x: Tensor, workers: int) -> tuple[Tensor, Tensor, Tensor]:
        if self._pool is None or self._pool_size < workers:
            self._pool = ThreadPoolExecutor(workers, thread_name_prefix="neural-solver")
            self._pool_size = workers
        parts = list(self._pool.map(lambda part: self._forward(part, CHUNK_SETS), x.tensor_split(workers)))
        return tuple(torch.cat(p) for p in zip(*parts, strict=True))

    def warm_up(self) -> None:
        """Nothing to compile: the network is ready once loaded."""

    def __call__(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        if minimal_sets.ndim != 3 or minimal_sets.shape[-1] != 3:
            raise ValueError(f"minimal_sets must be (H, C, 3), got {tuple(minimal_sets.shape)}")
        x = minimal_sets.detach().to(self.device, torch.float32)
        if self.device.type != "cpu":
            out = self._forward(x, max(1, x.shape[0]))  # a GPU wants one batch
        else:
            workers = min(self.threads or torch.get_num_threads(), -(-x.shape[0] // CHUNK_SETS))
            with _intra_op_threads(1):
                out = self._forward_parallel(x, workers) if workers > 1 else self._forward(x, CHUNK_SETS)
        # Cloned outside inference mode: callers may update the results in place or use them in autograd.
        return tuple(o.to(minimal_sets.device, minimal_sets.dtype).clone() for o in out)


def build(inputs) -> NeuralSolver:
    """The solver of the parts registry (``neural``) from a ``BuildInputs``: the network in
    ``inputs.weights`` (found by the factories) on ``inputs.device``, held to the fit's size bounds."""
    return NeuralSolver(weights=inputs.weights, device=inputs.device, bounds=SizeBounds.of(inputs.config))
