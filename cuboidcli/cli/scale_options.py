"""Scale-out options of ``cuboids fit DIR`` and ``cuboids evaluate`` (cuboidcli/scaleout.py runs them)."""

from __future__ import annotations

import typer

from cuboidcli.cli.common import fail


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
        "ray://HOST:10001); implies --ray. Needs: pip install 'cuboids\\[ray]'.",  # \\[: rich markup
    )


def ray_target(workers: int, ray: bool, ray_address: str | None) -> str | None:
    """The ``ray`` argument of :func:`cuboidcli.scaleout.run_tasks` for these options (None: no Ray, "": a
    local Ray); checks ``--workers``."""
    if workers < 1:
        fail(f"--workers must be at least 1 (got {workers})")
    if ray_address is not None and not ray_address.strip():
        fail("--ray-address is empty: give 'auto', HOST:PORT or ray://HOST:10001, or use --ray alone")
    return ray_address if ray_address is not None else ("" if ray else None)


def skip_existing_option(help: str):
    return typer.Option(True, "--skip-existing/--no-skip-existing", help=help)
