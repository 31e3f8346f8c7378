"""The rows of the table of options (:mod:`cuboidcli.cli.option_table`) for the ``cuboids train`` commands:
every option's type and valid range, in the same form as every other command's. A module of its own, so
that ``cuboids fit`` does not load the training package to check its options."""

from __future__ import annotations

from cuboidcli.fitting.checks import DEVICE, PATH, Check, choice, number, whole
from cuboidcli.fitting.config import CHECKS
from cuboidcli.learn.finetune_config import SOLVERS
from cuboidcli.learn.sampler_loss import CORR_MODES

SEED = CHECKS["seed"]
EPOCHS = whole(1, 100_000)
STEPS = whole(1, 10**9)
BATCH = whole(1, 100_000)
LR = number(0, 10, open_low=True)
#: A fine-tuning learning rate may be 0: that network stays fixed.
LR_OR_0 = number(0, 10)
THREADS = whole(1, 1024)
MINUTES = number(0, 10**7, open_low=True)
CHANNELS = whole(1, 4096)
BLOCKS = whole(0, 64)
UPSAMPLE = whole(1, 64, ok=lambda v: v & (v - 1) == 0, also="a power of two")
HYPOTHESES = whole(1, 100_000)
INSTANCES = whole(1, 1000)
SAMPLES_K = whole(2, 1000)
WEIGHT = number(0, 10**9)
FRAMES = whole(1, 10**9)
READERS = whole(1, 256)
BACKEND = choice(("gloo", "nccl"))

#: What every trainer takes: its output folder (and the old spelling), a checkpoint to resume, a seed,
#: a time limit and, with the ones that run on torch threads, the threads and the device.
RUN = {"out": PATH, "old_out": PATH, "resume": PATH, "seed": SEED, "max_minutes": MINUTES}
TORCH = {"threads": THREADS, "device": DEVICE}
#: The sampler's training and fine-tuning share these.
SCHEDULE = {
    "data": PATH,
    "epochs": EPOCHS,
    "batch": BATCH,
    "hypotheses": HYPOTHESES,
    "instances": INSTANCES,
    "samples_k": SAMPLES_K,
    "alpha": WEIGHT,
    "scenes_per_epoch": FRAMES,
    "grid_step": whole(1, 1000),
    "val_hypotheses": HYPOTHESES,
    "val_frames": FRAMES,
    "workers": READERS,
    "backend": BACKEND,
}

TRAIN_OPTIONS: dict[str, dict[str, Check]] = {
    "train solver": {
        **{("out_dir" if k == "out" else k): v for k, v in RUN.items()},
        **TORCH,
        "iters": STEPS,
        "batch": BATCH,
        "lr": LR,
        "width": CHANNELS,
        "old_width": CHANNELS,
        "layers": whole(1, 64),
        "heads": whole(1, 64),
        "ff": whole(1, 65_536),
        "val_every": STEPS,
        "backend": BACKEND,
    },
    "train sampler": {
        **RUN,
        **TORCH,
        **SCHEDULE,
        "lr": LR,
        "width": CHANNELS,
        "old_width": CHANNELS,
        "blocks": BLOCKS,
        "upsample": UPSAMPLE,
        "prior": choice(("unexplained", "none")),
        "kappa_corr": WEIGHT,
        "tau_c_start_sq_m2": number(0, 1000, open_low=True, unit="m^2"),
        "corr_mode": choice(CORR_MODES),
    },
    "train finetune": {
        **RUN,
        **TORCH,
        **SCHEDULE,
        "solver": choice(SOLVERS),
        **dict.fromkeys(("sampler_weights", "solver_weights", "depth_weights"), PATH),
        **dict.fromkeys(("lr", "solver_lr", "depth_lr"), LR_OR_0),
    },
    "train depth": {
        **RUN,
        **TORCH,
        "data": PATH,
        "epochs": EPOCHS,
        "batch": BATCH,
        "lr": LR,
        "l1_weight": WEIGHT,
        "min_crop": number(0, 1, open_low=True),
        "jitter": number(0, 1, open_high=True),
        "white_balance": number(0, 1, open_high=True),
        "blur": number(0, 100, unit="px"),
        "noise": number(0, 1),
        "grad_weight": WEIGHT,
        "init": PATH,
        "log_every": STEPS,
    },
    "train seed": {
        **RUN,
        "data": PATH,
        "scenes": FRAMES,
        "steps": whole(1, 1000),
        "hypotheses": HYPOTHESES,
        "kappa": number(0, 1000),
        "epochs": EPOCHS,
        "lr": LR,
        "width": CHANNELS,
        "old_width": CHANNELS,
        "blocks": BLOCKS,
        "upsample": UPSAMPLE,
    },
}
