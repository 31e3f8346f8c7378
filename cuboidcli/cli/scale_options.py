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


def run_with_progress(fn, tasks, names, engine, summary, quiet: bool, label: str, describe) -> None:
    """Run ``fn(*task)`` for every task on ``engine`` (an object with ``workers`` and ``ray``, as
    :func:`cuboidcli.scaleout.run_tasks` takes them) behind a progress bar titled ``label``. Each outcome
    joins ``summary``; its notes and a failure are printed in one line each, under the task's name in
    ``names``; ``describe(i, outcome)`` gives the bar's text for a finished task. One line and exit 2 when
    the engine cannot start."""
    from rich.progress import TimeElapsedColumn

    from cuboidcli.cli.common import console, progress_bar
    from cuboidcli.scaleout import run_tasks

    with progress_bar("{task.description}", TimeElapsedColumn(), disable=quiet) as prog:
        task = prog.add_task(label, total=len(tasks))

        def on_result(i: int, res) -> None:
            summary.add(res)
            for note in res.notes:
                console.print(f"[yellow]warning:[/] {names[i]}: {note}", highlight=False)
            if res.status == "failed":
                console.print(f"[red]failed[/] {names[i]}: {res.message}", highlight=False)
                desc = f"{names[i]}: failed"
            else:
                desc = describe(i, res)
            prog.update(task, advance=1, description=desc)

        if tasks:
            try:
                run_tasks(fn, tasks, names, workers=engine.workers, ray=engine.ray, on_result=on_result)
            except ValueError as e:  # the engine could not start (Ray missing, a bad address)
                fail(str(e))


def end_of_run(summary, out_dir, quiet: bool) -> None:
    """The run's summary line (always when something failed), and exit 1 if anything failed."""
    from cuboidcli.cli.common import out

    if not quiet or summary.failed:
        out.print(f"{summary.line()}: results in {out_dir}/")
    if summary.failed:
        raise typer.Exit(1)
