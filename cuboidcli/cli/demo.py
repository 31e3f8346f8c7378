"""`cuboids demo`: `cuboids fit` on the embedded sample scene, with every output."""

from __future__ import annotations

from pathlib import Path

import typer

from cuboidcli.cli.common import fail
from cuboidcli.cli.fit import fit
from cuboidcli.cli.options import call_with_defaults, config_option, device_option

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "data" / "sample"


def demo(
    output: Path = typer.Option(Path("cuboids_demo"), "--output", "-o", help="Output folder."),
    seed: int = config_option("seed"),
    device: str = device_option(),
) -> None:
    """Fit the embedded sample scene (a synthetic room) and write JSON, GLB, PLY and overlay PNGs."""
    from cuboidcli.export.files import result_name

    depth = SAMPLE_DIR / "sample_depth.png"
    if not depth.is_file():
        fail(f"the embedded sample is missing from {SAMPLE_DIR}; reinstall the package")
    call_with_defaults(  # cuboids fit with these options; the others are fit's defaults
        fit,
        image=SAMPLE_DIR / "sample.png",
        depth=depth,
        intrinsics=str(SAMPLE_DIR / "camera.json"),
        output=output / result_name(SAMPLE_DIR / "sample.png"),
        seed=seed,
        device=device,
        glb=True,
        ply=True,
        overlay=True,
        with_points=True,
    )


def register(app: typer.Typer) -> None:
    app.command()(demo)
