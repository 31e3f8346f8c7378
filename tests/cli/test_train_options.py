"""The options of the cuboids train commands are defined once (cuboidcli/cli/train_options.py): an option
named after a field of the config dataclass its command trains with takes that field's default."""

from __future__ import annotations

import dataclasses

from cuboidcli.cli.options import option_defaults
from cuboidcli.cli.train import train_app
from cuboidcli.cli.train_options import field_default

#: (command, field) -> (the CLI default, why it is not the field's default).
OTHER_DEFAULTS = {
    ("sampler", "prior"): (
        "unexplained",
        "the shipped sampler's recipe (models/sampler_v2.md); SamplerNetConfig keeps the paper's 'none' for "
        "nets and checkpoints made without the field",
    ),
}


def train_commands() -> dict:
    return {cmd.name: cmd.callback for cmd in train_app.registered_commands}


def test_every_train_command_names_its_configs():
    commands = train_commands()
    assert set(commands) == {"solver", "sampler", "finetune", "depth", "seed"}
    for name, command in commands.items():
        assert command.configs, name


def test_train_options_take_the_config_fields_defaults():
    checked = 0
    for name, command in train_commands().items():
        defaults = option_defaults(command)
        for cls in command.configs:
            for field in dataclasses.fields(cls):
                if field.name not in defaults:
                    continue
                expected = OTHER_DEFAULTS.get((name, field.name), (field_default(cls, field.name),))[0]
                assert defaults[field.name] == expected, (name, cls.__name__, field.name)
                checked += 1
    assert checked > 60


def test_options_named_after_fields_reach_the_config(monkeypatch, tmp_path):
    """The sampler command builds its configs from its options by name: a value given on the command line
    is in the config the trainer gets."""
    import cuboidcli.learn.sampler_train as sampler_train
    from cuboidcli.cli.options import call_with_defaults

    seen = {}

    def fake_train(cfg, data, out, net_cfg, **kwargs):
        seen.update(cfg=cfg, net_cfg=net_cfg)

    monkeypatch.setattr(sampler_train, "train_sampler", fake_train)
    data = tmp_path / "data"
    data.mkdir()
    (data / "splits.json").write_text("{}")
    command = train_commands()["sampler"]
    call_with_defaults(command, data=data, out=tmp_path / "out", tau_c_start_sq_m2=0.008, width=16, lr=3e-5)
    assert seen["cfg"].tau_c_start_sq_m2 == 0.008 and seen["cfg"].lr == 3e-5
    assert seen["net_cfg"].width == 16 and seen["net_cfg"].prior == "unexplained"


def test_the_seed_command_builds_its_config_from_its_options(monkeypatch, tmp_path):
    """``cuboids train seed`` (the first-point sampler, models/sampler_v3.pt) passes its options to
    SeedTrainConfig by name."""
    import cuboidcli.learn.seed_train as seed_train
    from cuboidcli.cli.options import call_with_defaults

    seen = {}
    monkeypatch.setattr(seed_train, "train_seed_sampler", lambda data, out, cfg, **kw: seen.update(cfg=cfg))
    data = tmp_path / "data"
    data.mkdir()
    call_with_defaults(train_commands()["seed"], data=data, out=tmp_path / "out", scenes=240, kappa=2.0)
    assert seen["cfg"] == seed_train.SeedTrainConfig(scenes=240, kappa=2.0)
