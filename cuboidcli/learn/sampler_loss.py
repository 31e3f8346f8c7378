"""Training losses of the sampling-weight network (paper Sec. 3.5 "Training" and "Regularisation").

One *instance* is one step of the sequential estimator with the state s = f_OAI(y, M) of the cuboids
selected so far. The network gives Q sampling-weight maps p_j over the N fitting points and selection
weights q. Shapes: ``log_p`` (Q, N) (log-probabilities, each row sums to 1 after exp), ``log_q`` (Q,),
points (N, 3) metres, state (N,).

Expected task loss L(w) = E_{H ~ p(H | M; w)}[l(h_hat, M)]: draw K hypothesis sets H_k of |H| hypotheses
each (a map j ~ q, then C points ~ p_j), fit them with the numerical solver (no gradient flows through
it) and score them with the occlusion-aware inlier count. With the probabilistic selection
p(h | H) = softmax(alpha I_i(h)) the expected loss of a set is E_h[l] = sum_h p(h | H) l(h), with the
task loss l(h) = -I_c(Y, M u {h}).
Its gradient is estimated as (1/K) sum_k [E_h[l]_k d log p(H_k; w) + d E_h[l]_k]; the second term is zero
for the sampler's weights because the hypotheses do not depend on them differentiably, so the sampler
learns from the policy gradient (REINFORCE) term alone:

    log p(H_k; w) = sum_{h in H_k} [ log q_{j(h)} + sum_{c=1..C} log p_{j(h)}(y_{h,c}) ],

which reaches EVERY map that was drawn at least once and, through the softmax of q, every selection
weight. (The authors' code recorded the sampled indices only for Q = 1, so for Q > 1 the maps received no
task gradient at all; see NOTES.md.) The mean of E_h[l] over the K sets is subtracted as a baseline.

Units and clamping. Inlier counts are divided by N (fractions of the fitting points), so that alpha = 10
(training) and 1000 (fine-tuning) act on gains in [0, 1] and the appendix's clamp of "losses to an
absolute maximum value of 0.3" is meaningful. The clamp is applied to the baseline-subtracted task loss
(the REINFORCE weight) only: it is the quantity that explodes with bad hypothesis samples early in
training, while the raw task loss of a good scene (about -0.7) must not be clipped and the regularisers
are bounded by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from cuboidcli.geometry.kernels import combine, oai_per_cuboid
from cuboidcli.sampling import draw_sets_and_maps
from cuboidcli.solvers.base import CuboidSolver


@dataclass(frozen=True)
class LossSettings:
    """The settings of the loss that a training config chooses (the others follow from the fitting config
    and the epoch), with the paper's symbols (appendix Table 7)."""

    hypotheses: int = 32
    """|H|: hypotheses per sampled set during training."""
    samples_k: int = 2
    """K: hypothesis sets sampled per instance (>= 2 for a non-zero baseline-subtracted signal)."""
    alpha: float = 10.0
    """alpha: softmax scale of the probabilistic selection, on gains in fractions of the points."""
    loss_clamp: float = 0.3
    """Clamp of the baseline-subtracted task loss (the REINFORCE weight), fractions of the points."""
    kappa_corr: float = 1.0
    """kappa_corr: weight of the map correlation loss."""
    corr_mode: str = "paper"
    """"paper": l_corr sums the correlation coefficients, so it keeps falling below 0 and rewards
    anti-correlated maps. "positive": only positive coefficients count (0 once the maps are uncorrelated
    or anti-correlated): it still prevents mode collapse, without rewarding the ripple patterns that
    minimise the paper's sum (seen in sampler_v1, docs/sampler_maps_v1.png)."""
    kappa_entropy: float = 1.0
    """kappa_entropy: weight of the negative entropy of q."""
    kappa_im: float = 0.01
    """kappa_im: weight of the inlier masking regularisation."""


@dataclass(frozen=True)
class LossParams(LossSettings):
    """Settings of one instance's loss: a training config's :class:`LossSettings` and those of the fit."""

    min_set: int = 6
    """C: points per minimal set."""
    tau_sq_m2: float = 0.004
    """tau: inlier threshold on the squared distance, m^2."""
    beta: float = 5.0
    """beta: softness of f_I."""
    tau_c_sq_m2: float = 1.0
    """tau_c: where f_O turns linear, m^2 (follows :func:`occlusion_threshold` during training)."""


def occlusion_threshold(epoch: int, epochs: int, tau_sq_m2: float, start_sq_m2: float = 1.0) -> float:
    """tau_c of an epoch (Sec. 3.2.4): tau_c = epoch / N_e (tau - 1) + 1, on SQUARED distances (m^2).

    The paper's formula interpolates linearly from 1 m^2 at epoch 0 (the penalty is then ~1 per occluded
    point up to 1 m and flat beyond, like the non-leaky f_O) down to tau itself at epoch N_e; the epochs
    actually run (0 .. N_e - 1) stop one step short of tau. It reaches the test value 2 tau only in the
    last ~0.4 % of the schedule, so training mostly sees a milder penalty than inference. ``start_sq_m2``
    generalises the "1" of the formula.
    """
    frac = min(max(epoch / max(epochs, 1), 0.0), 1.0)
    return start_sq_m2 + frac * (tau_sq_m2 - start_sq_m2)


def draw_sets(
    p: Tensor, q: Tensor, hypotheses: int, min_set: int, generator: torch.Generator
) -> tuple[Tensor, Tensor]:
    """Draw |H| minimal sets: map j(h) ~ q, then C point indices ~ p_j with replacement.

    p (Q, N), q (Q,) -> maps (H,) long, idx (H, C) long: the estimator's own drawing
    (:func:`cuboidcli.sampling.draw_sets_and_maps`), so training samples as inference does.
    """
    return draw_sets_and_maps(p, q, hypotheses, min_set, generator)


def set_log_prob(log_p: Tensor, log_q: Tensor, maps: Tensor, idx: Tensor) -> Tensor:
    """log p(H; w) of one hypothesis set: sum over h of log q_j(h) + sum_c log p_j(h)(y_c). Scalar.

    log_p (Q, N), log_q (Q,), maps (H,), idx (H, C).
    """
    maps = maps.to(log_p.device)
    idx = idx.to(log_p.device)
    point_terms = log_p[maps[:, None], idx]  # (H, C): each point's log-weight in its hypothesis' map
    return log_q[maps].sum() + point_terms.sum()


def correlation_matrix(p: Tensor, eps: float = 1e-12) -> Tensor:
    """Pearson correlation coefficients between the Q maps over the points: p (Q, N) -> (Q, Q)."""
    # Pearson is scale-invariant: rescale to mean 1 first so that weights of ~1/N do not underflow eps.
    p = p * p.shape[1]
    centred = p - p.mean(1, keepdim=True)
    cov = centred @ centred.T / p.shape[1]
    std = cov.diagonal().clamp_min(eps).sqrt()
    return cov / (std[:, None] * std[None, :])


CORR_MODES = ("paper", "positive")


def correlation_loss(p: Tensor, mode: str = "paper") -> Tensor:
    """l_corr: sum over ordered pairs i != j of corr(p_i, p_j) (``mode="paper"``) or of max(corr, 0)
    (``"positive"``). Q identical maps give Q (Q - 1) either way."""
    if mode not in CORR_MODES:
        raise ValueError(f"corr_mode must be one of {CORR_MODES}, got {mode!r}")
    c = correlation_matrix(p)
    off = c - torch.diag_embed(c.diagonal())
    return (off.clamp_min(0.0) if mode == "positive" else off).sum()


def entropy(q: Tensor) -> Tensor:
    """H(q) = -sum_j q_j log q_j in nats; log Q for a uniform q."""
    return -(q * torch.log(q.clamp_min(1e-30))).sum()


def entropy_loss(q: Tensor) -> Tensor:
    """l_entropy = -H(q): minimising it keeps every map selectable."""
    return -entropy(q)


def inlier_masking_loss(p: Tensor, state: Tensor) -> Tensor:
    """l_im: sampling weight on points the selected cuboids already explain (after CONSAC's IMR).

    Each map is scaled to a maximum of 1 (so the loss does not depend on how peaked it is) and weighted by
    the points' inlier value max(s, 0) in [0, 1]; the mean over maps and points is 0 when the maps avoid
    the explained points and approaches 1 when they concentrate on them. p (Q, N), state (N,) -> scalar.
    """
    p_hat = p / p.amax(1, keepdim=True).clamp_min(1e-30)
    return (p_hat * state.clamp_min(0.0).to(p.device, p.dtype)[None]).mean()


@dataclass
class InstanceResult:
    """One instance's loss and what the trainer needs from it.

    ``loss`` scalar with gradient: the REINFORCE surrogate plus the weighted regularisers of l_final
    (its gradient is the module docstring's estimate; its value is not the expected loss).
    ``expected_loss``: mean over the K sets of E_h[l], fractions of N. ``best_values`` (N,): f_OAI of
    the hypothesis with the largest gain over all K sets, for the state update. The rest are floats for
    logging.
    """

    loss: Tensor
    expected_loss: float
    best_values: Tensor
    best_gain: float
    mean_gain: float
    corr: float
    entropy: float
    im: float
    maps_drawn: list[int]


def instance_loss(
    log_p: Tensor,
    log_q: Tensor,
    points: Tensor,
    state: Tensor,
    solver: CuboidSolver,
    lp: LossParams,
    generator: torch.Generator,
    log_p_corr: Tensor | None = None,
) -> InstanceResult:
    """The loss of one instance (see the module docstring). log_p (Q, N), log_q (Q,), points (N, 3) m,
    state (N,) float64. ``log_p_corr`` (Q, N): the maps the correlation loss looks at (default log_p;
    the sampler passes its maps without the shared prior)."""
    n = points.shape[0]
    # f_OAI in float32 is ~3x faster than float64 on the CPU; values are O(1) and the sums over N points
    # are taken in float64 after the combination with the state.
    pts32 = points.float()
    p, q = log_p.exp(), log_q.exp()
    exp_losses, log_probs = [], []
    best_gain, best_values, gains_sum = -float("inf"), None, 0.0
    maps_drawn: set[int] = set()
    for _ in range(lp.samples_k):
        maps, idx = draw_sets(p, q, lp.hypotheses, lp.min_set, generator)
        maps_drawn.update(maps.tolist())
        with torch.no_grad():
            centers, half, rot = solver(points[idx])
            values = oai_per_cuboid(
                pts32, centers.float(), half.float(), rot.float(), lp.tau_sq_m2, lp.beta, lp.tau_c_sq_m2
            ).double()  # (H, N)
            joint = combine(values, state[None])
            gains = (joint - state[None]).sum(1) / n  # I_i = I_c(M u {h}) - I_c(M), over N
            task = -joint.sum(1) / n  # l(h) = -I_c(Y, M u {h}) / N
            selection = torch.softmax(lp.alpha * gains, 0)  # p(h | H, M), the probabilistic selection
            exp_losses.append((selection * task).sum())
        log_probs.append(set_log_prob(log_p, log_q, maps, idx))
        k_best = int(torch.argmax(gains))
        gains_sum += float(gains.mean())
        if float(gains[k_best]) > best_gain:
            best_gain, best_values = float(gains[k_best]), values[k_best]
    exp_loss = torch.stack(exp_losses)  # (K,)
    advantage = (exp_loss - exp_loss.mean()).clamp(-lp.loss_clamp, lp.loss_clamp)
    policy = (advantage.to(log_p.dtype) * torch.stack(log_probs)).mean()
    p_corr = p if log_p_corr is None else log_p_corr.exp()
    l_corr = correlation_loss(p_corr, lp.corr_mode)
    l_ent = entropy_loss(q)
    l_im = inlier_masking_loss(p, state)
    loss = policy + lp.kappa_corr * l_corr + lp.kappa_entropy * l_ent + lp.kappa_im * l_im
    return InstanceResult(
        loss=loss,
        expected_loss=float(exp_loss.mean()),
        best_values=best_values,
        best_gain=best_gain,
        mean_gain=gains_sum / lp.samples_k,
        corr=float(l_corr.detach()),
        entropy=-float(l_ent.detach()),
        im=float(l_im.detach()),
        maps_drawn=sorted(maps_drawn),
    )
