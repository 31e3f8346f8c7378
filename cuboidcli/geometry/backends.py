"""Which of the two kernel families runs on a device: the fused numba loops (:mod:`.fused`, the CPU only)
or the torch kernels (:mod:`.kernels`, any device), or, for "auto" on a GPU, both ("hybrid"): the GPU
scores whole batches of hypotheses with torch, and the CPU does the small sequential work with numba
(solving the minimal sets, refining and growing one winner), where a GPU would spend its time launching
kernels.

One rule for every caller that has both: the scoring backend of a fit (:mod:`cuboidcli.fitting.backend`)
and the numerical solver (:class:`cuboidcli.solvers.numerical.NumericalSolver`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch

#: Backend names: "auto" = numba on the CPU, "hybrid" elsewhere; "numba"; "torch".
BACKENDS = ("auto", "numba", "torch")


def resolve_backend(name: str, device: torch.device | str) -> str:
    """The kernel family ``name`` (one of :data:`BACKENDS`) means on ``device``: "numba", "torch" or
    "hybrid" (torch for batches on the device, numba on the CPU for the rest).

    Raises ValueError for an unknown name, or for "numba" on a device other than the CPU (the numba
    loops read the points' memory directly and run on the CPU only). ``device``: a torch device or its
    name ("cpu", "cuda:1"); read without torch, which a fit on numpy arrays never imports."""
    kind = device.type if hasattr(device, "type") else str(device).split(":")[0]
    if name == "auto":
        return "numba" if kind == "cpu" else "hybrid"
    if name == "torch":
        return "torch"
    if name == "numba":
        if kind != "cpu":
            raise ValueError(
                f"the numba backend runs on the CPU only, but the points are on {kind}; "
                "use backend='torch' or 'auto' on this device, or fit on the CPU"
            )
        return "numba"
    raise ValueError(f"unknown backend {name!r}; choose one of {', '.join(BACKENDS)}")
