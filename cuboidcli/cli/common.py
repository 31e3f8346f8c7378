"""Shared console, error exit and option helpers for every subcommand."""

from __future__ import annotations

import warnings
from contextlib import contextmanager

import typer
from rich.console import Console

console = Console(stderr=True)
out = Console()


def fail(message: str, code: int = 2) -> None:
    """Print a one-line error and exit with ``code``."""
    console.print(f"[bold red]error:[/] {message}", highlight=False, soft_wrap=True)
    raise typer.Exit(code)


@contextmanager
def user_errors():
    """Turn library input errors into one-line messages with exit code 2; show warnings in yellow."""
    from cuboidcli.io.depth import InputError

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except InputError as e:
            fail(str(e))
        except FileNotFoundError as e:
            fail(str(e))
        finally:
            for w in caught:
                console.print(f"[yellow]warning:[/] {w.message}", highlight=False, soft_wrap=True)


def check_training_paths(data, resume, out) -> None:
    """The checks every ``cuboids train`` command makes of its DATA folder, ``--resume`` and ``--out``."""
    if not data.is_dir():
        fail(f"dataset folder not found: {data}")
    if resume is not None and not resume.is_file():
        fail(f"--resume {resume}: no such checkpoint (give OUT/last.pt)")
    if out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a folder")


def resolve_device(device: str) -> str:
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device == "cuda" and not torch.cuda.is_available():
        fail("--device cuda: no CUDA device is available; use --device cpu or auto")
    if device not in ("cpu", "cuda"):
        fail(f"--device {device!r}: choose auto, cpu or cuda")
    return device


# Scale-out options shared by `cuboids fit DIR` and `cuboids evaluate` (cuboidcli/scaleout.py runs them).
def workers_option():
    return typer.Option(1, "--workers", help="Run frames in N local processes (the same results as 1).")


def ray_option():
    return typer.Option(
        False, "--ray", help="Run frames as Ray tasks on a Ray started here (--workers CPUs)."
    )


def ray_address_option():
    return typer.Option(
        None,
        "--ray-address",
        help="Run frames as Ray tasks on this Ray cluster ('auto': the one this machine belongs to, "
        "ray://HOST:10001); implies --ray. Needs: pip install 'cuboids[ray]'.",
    )


def ray_target(workers: int, ray: bool, ray_address: str | None) -> str | None:
    """The ``ray`` argument of :func:`cuboidcli.scaleout.run_tasks` for these options (None: no Ray, "": a
    local Ray); checks ``--workers``."""
    if workers < 1:
        fail(f"--workers must be at least 1 (got {workers})")
    if ray_address is not None and not ray_address.strip():
        fail("--ray-address is empty: give 'auto', HOST:PORT or ray://HOST:10001, or use --ray alone")
    return ray_address if ray_address is not None else ("" if ray else None)
