"""The hypothesis-draw generators of a data-parallel sampler training or fine-tuning run: one per rank,
seeded so that the ranks' streams never meet, and their states in the training state (``draw_rngs``) so
that a resumed run continues each rank's stream."""

from __future__ import annotations

import torch

from cuboidcli.learn.distributed import DistContext

#: Rank r's draw seed is offset by r * RANK_SEED_STRIDE and a rank new to a resumed run's by the epoch times
#: EPOCH_SEED_STRIDE: the streams cannot meet as long as 0 <= seed < 2^32, epochs < 2^16 and ranks < 2^15.
RANK_SEED_STRIDE = 2**48
EPOCH_SEED_STRIDE = 2**32


def draw_seed(seed: int, rank: int = 0, epoch: int = 0) -> int:
    """Seed of the hypothesis-draw generator of ``rank``, started at ``epoch`` (0 for a fresh run, the
    resume epoch for a rank the checkpoint has no state for). Rank 0 of a fresh run: ``seed + 1``, the
    single-process stream."""
    return seed + 1 + rank * RANK_SEED_STRIDE + epoch * EPOCH_SEED_STRIDE


def draw_generator(seed: int, ctx: DistContext, state: dict | None, epoch: int) -> torch.Generator:
    """This rank's hypothesis-draw generator: :func:`draw_seed` of a fresh run, or the rank's state in a
    resumed run's ``draw_rngs`` (a rank the checkpoint has no state for, resumed on more processes than it
    was written by, starts the fresh stream of its rank and the resume epoch)."""
    gen = torch.Generator().manual_seed(draw_seed(seed, ctx.rank))  # rank 0: seed + 1
    if state is not None:
        draw_rngs = state.get("draw_rngs") or [state["draw_rng"]]  # older checkpoints: rank 0's only
        if ctx.rank < len(draw_rngs):
            gen.set_state(draw_rngs[ctx.rank])
        else:
            gen.manual_seed(draw_seed(seed, ctx.rank, epoch))
    return gen


def draw_states(gen: torch.Generator, ctx: DistContext) -> dict:
    """The training-state entries of the draw generators: every rank's (``draw_rngs``, a collective) and
    rank 0's (``draw_rng``, as single-process checkpoints hold it)."""
    return {"draw_rng": gen.get_state(), "draw_rngs": ctx.gather(gen.get_state())}
