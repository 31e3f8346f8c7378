"""Data-parallel training across processes with torch's own DistributedDataParallel, launched by ``torchrun``.

``torchrun`` starts one process per device and tells each who it is through environment variables
(``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK``, ``MASTER_ADDR``, ``MASTER_PORT``). Without them, or with a world
of one, everything here degrades to a plain single process: no process group, no collectives, so a
single-process run is exactly what it was before multi-process support existed.

The training loops ask these things of this module: who am I (:class:`DistContext`), make every rank
see the same value (:meth:`DistContext.broadcast_float`), what is the mean over the ranks
(:meth:`DistContext.mean_float`), sum the gradients over the ranks when the loop does it by hand instead
of through DistributedDataParallel (:meth:`DistContext.sum_gradients`), and are the replicas still
identical (:func:`state_sha256` with :meth:`DistContext.gather`).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

import torch
import torch.distributed as dist

T = TypeVar("T")

#: Overrides the process-group backend when no explicit one is passed (gloo, nccl, ...).
BACKEND_ENV = "CUBOIDS_DIST_BACKEND"


def launched_world_size() -> int:
    """Processes in the job according to the launcher's environment (1 when not launched by torchrun)."""
    return int(os.environ.get("WORLD_SIZE", "1"))


def launched_rank() -> int:
    """Global rank of this process according to the launcher's environment (0 when not launched)."""
    return int(os.environ.get("RANK", "0"))


@dataclass(frozen=True)
class DistContext:
    """This process's place in the job. ``world_size == 1`` means no process group exists."""

    rank: int = 0
    """Global rank, 0 .. world_size - 1; rank 0 alone writes files and reports progress."""
    local_rank: int = 0
    """Rank on this node: picks the GPU (``cuda:local_rank``)."""
    world_size: int = 1
    backend: str | None = None
    """Process-group backend, None for a single process."""

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def active(self) -> bool:
        return self.world_size > 1

    def broadcast_float(self, value: float) -> float:
        """Rank 0's ``value`` on every rank. Used for decisions taken from wall time (the time budget):
        clocks differ between processes, and ranks that disagree on the lr or on when to stop would
        diverge or deadlock in the next gradient all-reduce."""
        if not self.active:
            return value
        device = torch.device("cuda", self.local_rank) if self.backend == "nccl" else torch.device("cpu")
        # float64: the time fraction must survive the trip exactly, rank 0 compares it with 1.0 too.
        box = torch.tensor([value], dtype=torch.float64, device=device)
        dist.broadcast(box, src=0)
        return float(box.item())

    def mean_float(self, value: float) -> float:
        """Mean of ``value`` over the ranks, on every rank (e.g. the training loss of the global batch)."""
        if not self.active:
            return value
        device = torch.device("cuda", self.local_rank) if self.backend == "nccl" else torch.device("cpu")
        box = torch.tensor([value], dtype=torch.float64, device=device)
        dist.all_reduce(box)
        return float(box.item()) / self.world_size

    def gather(self, obj: object) -> list[object]:
        """Every rank's ``obj`` (picklable), in rank order, on every rank."""
        if not self.active:
            return [obj]
        out: list[object] = [None] * self.world_size
        dist.all_gather_object(out, obj)
        return out

    def share(self, items: Sequence[T]) -> Sequence[T]:
        """This rank's part of ``items``: items r, r + W, r + 2W, ... (all of them in one process)."""
        return items[self.rank :: self.world_size]

    def gather_shares(self, mine: list, total: int) -> list:
        """Per-item results of every rank's :meth:`share` of ``total`` items, back in item order, on every
        rank (a collective)."""
        shards = self.gather(mine)
        return [shards[i % self.world_size][i // self.world_size] for i in range(total)]

    def barrier(self) -> None:
        if self.active:
            dist.barrier()

    def sum_gradients(self, params: Iterable[torch.Tensor]) -> None:
        """Replace every parameter's ``.grad`` by its sum over the ranks, on every rank (one all-reduce per
        dtype): the manual counterpart of DistributedDataParallel's hook, for loops that call the model
        several times per step. A parameter that has a gradient on some rank but not on this one counts
        as zeros here; one without a gradient on every rank keeps ``None`` (the optimizer skips it, as it
        would in a single process). The reduced values are bit-identical on all ranks."""
        if not self.active:
            return
        params = [p for p in params if p.requires_grad]
        if not params:
            return
        has = torch.tensor([p.grad is not None for p in params], dtype=torch.int32, device=params[0].device)
        dist.all_reduce(has)
        used = [p for p, n in zip(params, has.tolist(), strict=True) if n > 0]
        for p in used:
            if p.grad is None:
                p.grad = torch.zeros_like(p)
        for dtype in sorted({p.grad.dtype for p in used}, key=str):
            group = [p for p in used if p.grad.dtype == dtype]
            flat = torch.cat([p.grad.reshape(-1) for p in group])
            dist.all_reduce(flat)
            offset = 0
            for p in group:
                n = p.grad.numel()
                p.grad.copy_(flat[offset : offset + n].view_as(p.grad))
                offset += n


def default_backend(device: str) -> str:
    """nccl for CUDA devices, gloo otherwise, unless ``CUBOIDS_DIST_BACKEND`` says otherwise."""
    return os.environ.get(BACKEND_ENV) or ("nccl" if device.startswith("cuda") else "gloo")


@contextmanager
def distributed(device: str = "cpu", backend: str | None = None) -> Iterator[DistContext]:
    """Join the job described by torchrun's environment for the duration of the block.

    Initialises the default process group when ``WORLD_SIZE > 1`` and destroys it on the way out, also
    after an error (a leaked group would make a later run in the same process fail to initialise). A group
    the caller already initialised is used as it is and left alone.
    """
    world = launched_world_size()
    if world <= 1:
        yield DistContext()
        return
    owned = not dist.is_initialized()
    if owned:
        if not dist.is_available():
            raise RuntimeError("WORLD_SIZE > 1 but this torch build has no torch.distributed")
        backend = backend or default_backend(device)
        if backend == "nccl":
            # nccl needs the device chosen before the group starts, one GPU per local rank.
            torch.cuda.set_device(int(os.environ.get("LOCAL_RANK", "0")))
        dist.init_process_group(backend=backend)  # reads MASTER_ADDR/PORT, RANK, WORLD_SIZE
    try:
        yield DistContext(
            rank=dist.get_rank(),
            local_rank=int(os.environ.get("LOCAL_RANK", "0")),
            world_size=dist.get_world_size(),
            backend=dist.get_backend(),
        )
    finally:
        if owned:
            dist.destroy_process_group()


def state_sha256(state_dict: dict[str, torch.Tensor]) -> str:
    """SHA-256 over the names and raw bytes of a state dict's tensors, in order: equal hashes across ranks
    prove the replicas hold bit-identical weights."""
    h = hashlib.sha256()
    for name, tensor in state_dict.items():
        h.update(name.encode())
        h.update(tensor.detach().cpu().contiguous().reshape(-1).view(torch.uint8).numpy().tobytes())
    return h.hexdigest()
