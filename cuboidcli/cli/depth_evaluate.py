"""Depth errors of a depth estimator on an RGB-D dataset folder:
``python -m cuboidcli.cli.depth_evaluate DATA [--model PATH] [--split NAME] [--filled] [--output FILE.json]``.

The work is :func:`cuboidcli.depth.evaluate.evaluate_dataset`; this module parses the options and prints one
line per frame and their mean on stdout.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import typer

from cuboidcli.cli.common import fail, run_as_module, user_errors
from cuboidcli.cli.renamed import prefer_new, renamed_option

PROG = "python -m cuboidcli.cli.depth_evaluate"


def evaluate_depth_cmd(
    data: Path = typer.Argument(..., help="RGB-D dataset folder (the layout of 'cuboids synth', or flat)."),
    model: Path | None = typer.Option(
        None,
        "--model",
        help="Built-in .pt checkpoint or metric .onnx \\[default: the shipped network].",  # \\[: rich markup
    ),
    split: str | None = typer.Option(None, "--split", help="Only the frames of this split (splits.json)."),
    filled: bool = typer.Option(False, "--filled", help="Use in-painted ground truth where both exist."),
    output: Path | None = typer.Option(None, "--output", "-o", help="Write the report as JSON."),
    out: Path | None = renamed_option("--out", "--output"),
) -> None:
    """Depth errors (AbsRel, RMSE, delta < 1.25) of a depth estimator on an RGB-D dataset folder."""
    from cuboidcli.depth.evaluate import evaluate_dataset
    from cuboidcli.factories import make_depth_estimator
    from cuboidcli.io.atomic import atomic_write_json
    from cuboidcli.weights import resolve

    output = prefer_new(output, out, "--out", "--output")
    path = resolve("depth", model)
    with user_errors():
        try:
            report = evaluate_dataset(make_depth_estimator(path), data, split, raw=not filled)
        except ValueError as e:
            fail(str(e))
    report["model"] = {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}
    report["data"] = str(data)
    for name, errors in [*report["frames"].items(), ("mean", report["mean"])]:
        typer.echo(
            f"{name:24s} AbsRel {errors['abs_rel']:.3f}  RMSE {errors['rmse_m']:.3f} m  "
            f"d<1.25 {errors['delta1']:.3f}"
        )
    if output:
        atomic_write_json(output, report)


def main(argv: list[str] | None = None) -> None:
    """``python -m cuboidcli.cli.depth_evaluate ARGV`` (``argv`` None: the process's arguments)."""
    from cuboidcli.cli.option_table import check_options

    run_as_module(evaluate_depth_cmd, argv, PROG, prepare=lambda c: check_options(c, "depth_evaluate"))


if __name__ == "__main__":
    main()
