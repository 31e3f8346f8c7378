"""The one weights format of the networks: a plain dict ``{"config", "state_dict", "meta"}``.

``config`` is the network's config dataclass as a dict (enough to rebuild the exact module), ``state_dict``
its tensors on the CPU, ``meta`` free-form provenance (epoch, validation, data). Such a dict loads with
``torch.load(weights_only=True)``: :func:`cuboidcli.io.checkpoints.load_net` reads a file and rebuilds the
network with the kind's ``net_from_checkpoint`` (which calls :func:`build_net`).
"""

from __future__ import annotations

from dataclasses import asdict, fields
from typing import ClassVar, TypeVar

from torch import nn

Net = TypeVar("Net", bound=nn.Module)


class NetConfig:
    """Base of the networks' frozen config dataclasses: to and from the plain dict a checkpoint stores
    (tuples are stored as lists)."""

    #: What the config is of, in messages ("sampler-net").
    label: ClassVar[str] = "net"

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict):
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown {cls.label} config keys {sorted(unknown)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def parameter_count(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters())


def checkpoint_dict(net: nn.Module, meta: dict | None = None) -> dict:
    """The weights file format ``{"config", "state_dict", "meta"}``, loadable with ``weights_only=True``."""
    state = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
    return {"config": net.config.to_dict(), "state_dict": state, "meta": dict(meta or {})}


def build_net(ckpt: dict, net_class: type[Net], config_class: type[NetConfig], what: str) -> Net:
    """Rebuild the exact net of a :func:`checkpoint_dict` on the CPU, in eval mode. ``what`` names the kind
    in the error for a dict without ``config`` and ``state_dict`` ("not a solver checkpoint")."""
    if not isinstance(ckpt, dict) or "config" not in ckpt or "state_dict" not in ckpt:
        raise ValueError(f"not a {what} checkpoint: expected a dict with 'config' and 'state_dict'")
    net = net_class(config_class.from_dict(ckpt["config"]))
    net.load_state_dict(ckpt["state_dict"])
    return net.eval()
