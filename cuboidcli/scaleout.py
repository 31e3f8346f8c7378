"""Running many independent frames: in this process, in local worker processes, or as Ray tasks.

Every frame is a task ``fn(*args)`` that returns an :class:`Outcome` and never raises for a bad frame (the
task functions of :mod:`cuboidcli.job` and :mod:`cuboidcli.evaluation.runner` catch their errors), so a
failed frame is reported and the others go on. A frame's result depends only on its inputs and the seed,
not on the process that runs it, so every engine gives the same results.

Engines (:func:`run_tasks`): ``workers=1`` runs the tasks here; ``workers=N`` in N spawned processes;
``ray=ADDRESS`` as Ray tasks of one CPU each on the cluster at ADDRESS (``auto``: the cluster this machine
belongs to), or ``ray=""`` on a Ray started here for this run (``workers`` CPUs, default all). At most a
few tasks per CPU are in flight, so a million-frame run does not hold a million futures.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from cuboidcli.io.atomic import OutputError

#: Tasks in flight per worker: enough to keep each busy while results come back.
IN_FLIGHT_PER_WORKER = 4


@dataclass
class Outcome:
    """What became of one frame."""

    name: str
    status: str
    """done | skipped (its valid output existed) | failed."""
    message: str = ""
    """For failed frames: the one-line reason."""
    value: object = None
    """What the task produced (e.g. the frame's metrics)."""
    notes: list[str] = field(default_factory=list)
    """Warnings about the frame's input."""


@dataclass
class Summary:
    """Counts of a run over many frames."""

    done: int = 0
    skipped: int = 0
    failed: int = 0

    def add(self, outcome: Outcome) -> None:
        setattr(self, outcome.status, getattr(self, outcome.status) + 1)

    def line(self) -> str:
        return f"{self.done} done, {self.skipped} skipped, {self.failed} failed"


def worker_init() -> None:
    """One thread per worker process: N processes share N cores (the results do not depend on it). A
    worker that fits frames on numpy arrays never imports torch; one that does (a room, a network) reads
    its thread count from OMP_NUM_THREADS when it first imports it."""
    import os
    import sys

    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)
    else:
        os.environ["OMP_NUM_THREADS"] = "1"
    try:
        import numba

        numba.set_num_threads(1)
    except (ImportError, ValueError):  # numba missing, or its thread pool already fixed
        pass


def failed(name: str, error: BaseException) -> Outcome:
    """The Outcome of a task that raised: input errors keep their message, anything else says its type."""
    from cuboidcli.io.depth import InputError

    text = (
        str(error)
        if isinstance(error, InputError | FileNotFoundError)
        else f"{type(error).__name__}: {error}"
    )
    return Outcome(name, "failed", text.splitlines()[0] if text else type(error).__name__)


def run_tasks(
    fn: Callable[..., Outcome],
    tasks: Sequence[tuple],
    names: Sequence[str],
    *,
    workers: int = 1,
    ray: str | None = None,
    on_result: Callable[[int, Outcome], None] | None = None,
) -> list[Outcome]:
    """Run ``fn(*task)`` for every task; returns the outcomes in task order and calls
    ``on_result(index, outcome)`` as they arrive. ``names`` name the tasks in failure reports. ``ray``:
    None = no Ray; "" = a local Ray of ``workers`` CPUs (``workers`` 1: all of them); an address (``auto``,
    ``ray://host:10001``, ``host:6379``) = that cluster. Raises ValueError if Ray is asked for and missing.
    A task that raises :class:`~cuboidcli.io.atomic.OutputError` (its results cannot be written: a full or
    read-only folder, which every later task would meet too) ends the run: the error is raised here."""
    if workers < 1:
        raise ValueError(f"workers must be at least 1 (got {workers})")
    outcomes: list[Outcome | None] = [None] * len(tasks)

    def record(i: int, outcome: Outcome) -> None:
        outcomes[i] = outcome
        if on_result is not None:
            on_result(i, outcome)

    if ray is not None:
        _run_ray(fn, tasks, names, ray, workers, record)
    elif workers == 1 or len(tasks) <= 1:
        for i, task in enumerate(tasks):
            try:
                record(i, fn(*task))
            except OutputError:
                raise
            except Exception as e:  # a task function that raised after all: still only this frame
                record(i, failed(names[i], e))
    else:
        _run_processes(fn, tasks, names, workers, record)
    return [o for o in outcomes if o is not None]


def _run_processes(fn, tasks, names, workers: int, record) -> None:
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from multiprocessing import get_context

    limit = workers * IN_FLIGHT_PER_WORKER
    todo = iter(range(len(tasks)))
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn"), initializer=worker_init) as pool:
        pending = {}
        for i in todo:
            pending[pool.submit(fn, *tasks[i])] = i
            if len(pending) >= limit:
                break
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                i = pending.pop(fut)
                try:
                    record(i, fut.result())
                except OutputError:
                    pool.shutdown(cancel_futures=True)
                    raise
                except Exception as e:  # the worker process died (memory, a crash in native code)
                    record(i, failed(names[i], e))
                nxt = next(todo, None)
                if nxt is not None:
                    pending[pool.submit(fn, *tasks[nxt])] = nxt


def _ray_task(fn, args: tuple) -> Outcome:
    """What each Ray task runs: the worker set-up once per worker process, then the frame."""
    global _RAY_WORKER_READY
    if not _RAY_WORKER_READY:
        worker_init()
        _RAY_WORKER_READY = True
    return fn(*args)


_RAY_WORKER_READY = False


def _run_ray(fn, tasks, names, address: str, workers: int, record) -> None:
    try:
        import ray
    except ImportError as e:
        raise ValueError("--ray needs Ray: pip install 'cuboids[ray]'") from e
    started = not ray.is_initialized()
    if started:
        try:
            if address:
                ray.init(address=address, log_to_driver=False, logging_level=logging.WARNING)
            else:
                cpus = workers if workers > 1 else os.cpu_count()
                ray.init(
                    num_cpus=cpus, include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING
                )
        except Exception as e:  # no cluster at that address, a version mismatch, no resources
            where = f"the Ray cluster at {address}" if address else "a local Ray"
            raise ValueError(
                f"cannot start or reach {where}: {str(e).splitlines()[0] if str(e) else e!r}"
            ) from e
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_ray_task)
        limit = max(1, int(ray.cluster_resources().get("CPU", workers))) * IN_FLIGHT_PER_WORKER
        todo = iter(range(len(tasks)))
        pending = {}
        for i in todo:
            pending[remote.remote(fn, tasks[i])] = i
            if len(pending) >= limit:
                break
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                i = pending.pop(ref)
                try:
                    record(i, ray.get(ref))
                except Exception as e:  # the task or its worker failed (RayTaskError, WorkerCrashedError)
                    if isinstance(getattr(e, "cause", None), OutputError):
                        raise e.cause from None
                    record(i, failed(names[i], getattr(e, "cause", None) or e))
                nxt = next(todo, None)
                if nxt is not None:
                    pending[remote.remote(fn, tasks[nxt])] = nxt
    finally:
        if started:
            ray.shutdown()
