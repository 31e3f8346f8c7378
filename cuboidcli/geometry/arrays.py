"""The few array operations the estimator needs on both kinds of arrays it holds its data in: numpy arrays
(a frame fitted on the CPU by the numba kernels and parts that take numpy) and torch tensors (a GPU, the
torch kernels, the networks, a room). Each function takes either kind and gives back the kind it was
given, on the same device; torch is never imported here, so a fit on numpy arrays runs without it.

Random numbers come from the generator a fit was seeded with: a :class:`numpy.random.Generator` for
numpy arrays (:func:`generator`), a ``torch.Generator`` for tensors. Both are deterministic for a seed and
independent of the thread count; the two draw different numbers for the same seed.
"""

from __future__ import annotations

import sys
from contextlib import nullcontext
from typing import Any

import numpy as np

Array = Any
"""A numpy array or a torch tensor."""


def is_tensor(x) -> bool:
    """Whether ``x`` is a torch tensor (False without importing torch when it is not loaded)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


def is_torch_generator(gen) -> bool:
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(gen, torch.Generator)


def namespace(x):
    """The module whose functions take ``x``: torch for a tensor, numpy otherwise (for the functions both
    spell alike: minimum, maximum, where, ...)."""
    return sys.modules["torch"] if is_tensor(x) else np


def device_of(x) -> str:
    """The device kind of ``x``: "cpu" for a numpy array, the tensor's device type otherwise."""
    return x.device.type if is_tensor(x) else "cpu"


def numpy64(x) -> np.ndarray:
    """``x`` as a float64 numpy array on the CPU (no copy for a float64 array)."""
    if is_tensor(x):
        return x.detach().double().cpu().numpy()
    return np.asarray(x, dtype=np.float64)


def float64(x):
    """``x`` in float64, of its own kind."""
    return x.double() if is_tensor(x) else np.asarray(x, dtype=np.float64)


def float32(x):
    """``x`` in float32, of its own kind."""
    return x.float() if is_tensor(x) else np.asarray(x, dtype=np.float32)


def like(a: np.ndarray, ref):
    """The numpy array ``a`` as the kind, dtype and device of ``ref``."""
    if is_tensor(ref):
        import torch

        return torch.from_numpy(np.ascontiguousarray(a)).to(device=ref.device, dtype=ref.dtype)
    return np.asarray(a, dtype=ref.dtype)


def cast_like(x, ref):
    """``x`` (a numpy array, or a tensor when ``ref`` is one) in ``ref``'s kind and dtype, on its device."""
    if is_tensor(ref):
        if not is_tensor(x):
            import torch

            x = torch.from_numpy(np.ascontiguousarray(x))
        return x.to(device=ref.device, dtype=ref.dtype)
    return np.asarray(x, dtype=ref.dtype)


def as_kind(x, ref):
    """``x`` (either kind) as ``ref``'s kind, keeping its dtype; a tensor goes to ``ref``'s device."""
    if is_tensor(ref):
        import torch

        return (torch.from_numpy(np.asarray(x)) if not is_tensor(x) else x).to(ref.device)
    return x.detach().cpu().numpy() if is_tensor(x) else np.asarray(x)


def on_cpu_as(a: np.ndarray, ref):
    """The numpy array ``a`` as ``ref``'s kind, on the CPU (a tensor shares its memory)."""
    if is_tensor(ref):
        import torch

        return torch.from_numpy(a)
    return a


def copy(x):
    return x.clone() if is_tensor(x) else x.copy()


def count(x) -> int:
    """The number of elements of ``x``."""
    return int(x.numel()) if is_tensor(x) else int(np.size(x))


def indices(mask):
    """The indices (M,) where the 1-D boolean ``mask`` is true, of its kind."""
    return mask.nonzero().squeeze(1) if is_tensor(mask) else np.flatnonzero(mask)


def cat(parts: list):
    """The arrays of ``parts`` (all of one kind) joined along their first axis."""
    if is_tensor(parts[0]):
        import torch

        return torch.cat(parts)
    return np.concatenate(parts)


def zeros(n: int, ref):
    """(n,) float64 zeros of ``ref``'s kind and device."""
    if is_tensor(ref):
        import torch

        return torch.zeros(n, dtype=torch.float64, device=ref.device)
    return np.zeros(n)


def clamp(x, lo: float | None = None, hi: float | None = None):
    """``x`` clipped to [lo, hi] (None: no bound)."""
    return x.clamp(lo, hi) if is_tensor(x) else np.clip(x, lo, hi)


def no_grad(x):
    """A context without autograd for tensors; nothing for numpy arrays."""
    if is_tensor(x):
        import torch

        return torch.no_grad()
    return nullcontext()


def generator(seed: int, ref=None):
    """The random generator of a fit seeded with ``seed``: torch's CPU generator where the fit's data are
    tensors (``ref``), numpy's (PCG64) otherwise."""
    if ref is not None and is_tensor(ref):
        import torch

        return torch.Generator().manual_seed(seed)
    return np.random.default_rng(seed)


def randperm(n: int, gen):
    """A random permutation of range(n), int64, of the generator's kind (on the CPU)."""
    if is_torch_generator(gen):
        import torch

        return torch.randperm(n, generator=gen)
    return gen.permutation(n)


def categorical(p, k: int, gen) -> np.ndarray:
    """``k`` draws with replacement from the distribution ``p`` (N,) (non-negative, summing to about 1):
    int64 (k,) numpy indices. A draw never lands on an entry of weight 0."""
    if is_torch_generator(gen):
        import torch

        return torch.multinomial(p, k, replacement=True, generator=gen).numpy()
    p = np.asarray(p, dtype=np.float64)
    cdf = np.cumsum(p)
    idx = np.searchsorted(cdf, gen.random(k) * cdf[-1], side="right")
    # a uniform rounded up to the total lands past the end: the last entry that can be drawn
    return np.minimum(idx, np.flatnonzero(p > 0)[-1]).astype(np.int64)


def randint(high: int, n: int, gen) -> np.ndarray:
    """``n`` integers uniform in [0, high): int64 numpy (n,)."""
    if is_torch_generator(gen):
        import torch

        return torch.randint(high, (n,), generator=gen).numpy()
    return gen.integers(0, high, n, dtype=np.int64)


def sorted_uniforms(n: int, m: int, gen) -> np.ndarray:
    """(n, m) float64 uniforms in [0, 1), each row sorted: numpy."""
    if is_torch_generator(gen):
        import torch

        return torch.rand(n, m, generator=gen, dtype=torch.float64).sort(1).values.numpy()
    return np.sort(gen.random((n, m)), axis=1)


def indices_of_generator(idx: np.ndarray, gen):
    """int64 indices drawn with ``gen`` (numpy) as its kind: torch tensors for a torch generator (what the
    torch code that draws them expects), numpy otherwise."""
    if is_torch_generator(gen):
        import torch

        return torch.from_numpy(idx)
    return idx
