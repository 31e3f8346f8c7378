"""Shared console, error exit and option helpers for every subcommand.

Errors a user can act on end a command with one line on stderr and exit status 2 (:func:`fail`); an
unexpected exception ends it with one line naming the file that holds its traceback and status 1
(:func:`report_crash`; ``cuboids --debug`` shows the traceback instead). Warnings of the libraries
(OpenCV, numba, torch) stay out of the normal output (:func:`quiet_libraries`); the tool's own input
warnings are printed in yellow.
"""

from __future__ import annotations

import os
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

console = Console(stderr=True)
out = Console()

#: Library modules whose Python warnings are hidden unless ``--debug`` is given.
LIBRARY_MODULES = r"(torch|numba|llvmlite|cv2|numpy|onnx|onnxruntime|open3d|trimesh|h5py|OpenEXR)(\.|$)"


def fail(message: str, code: int = 2) -> None:
    """Print a one-line error and exit with ``code``."""
    console.print(f"[bold red]error:[/] {escape(str(message))}", highlight=False, soft_wrap=True)
    raise typer.Exit(code)


def quiet_libraries() -> None:
    """Keep the libraries' own warnings out of the output: OpenCV's log lines ("[ WARN:0@1.5] ... PNG
    input buffer is incomplete" next to the tool's message about the file) and Python warnings raised in
    torch, numba and the other libraries. The tool reports what matters about the input itself."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")  # read when cv2 is first imported
    if "cv2" in sys.modules:  # already imported: the environment variable came too late
        logging = sys.modules["cv2"].utils.logging
        logging.setLogLevel(logging.LOG_LEVEL_SILENT)
    warnings.filterwarnings("ignore", module=LIBRARY_MODULES)


def report_crash(exc: BaseException) -> Path | None:
    """Save the traceback of an unexpected exception to a file and print one line naming it.

    Returns the file (None when it could not be written; the line then says so)."""
    import datetime
    import tempfile
    import traceback

    from cuboidcli import __version__

    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    text = (
        f"cuboids {__version__}, python {sys.version.split()[0]}\n"
        f"command: {' '.join(['cuboids', *sys.argv[1:]])}\n\n"
        + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    )
    path: Path | None = Path(tempfile.gettempdir()) / f"cuboids-crash-{stamp}-{os.getpid()}.txt"
    try:
        path.write_text(text, encoding="utf-8")
        where = f"the traceback is in {path}"
    except OSError:
        path, where = None, "the traceback could not be saved"
    summary = " ".join(str(exc).split())[:200] or "no message"
    console.print(
        f"[bold red]error:[/] internal error ({type(exc).__name__}: {escape(summary)}); this is a bug in "
        f"cuboids: {where} (or run with 'cuboids --debug ...' to see it)",
        highlight=False,
        soft_wrap=True,
    )
    return path


@contextmanager
def user_errors():
    """Turn library input errors into one-line messages with exit code 2; show the tool's input warnings
    in yellow (the libraries' own warnings are dropped, see :func:`quiet_libraries`)."""
    from cuboidcli.io.depth import InputError, InputWarning

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
                if issubclass(w.category, InputWarning):
                    console.print(
                        f"[yellow]warning:[/] {escape(str(w.message))}", highlight=False, soft_wrap=True
                    )


def check_writable(folder: Path, flag: str = "-o") -> None:
    """One line, exit 2, before any work, when the output ``folder`` (or the nearest existing folder above
    it, where it is to be made) cannot be written to."""
    here = Path(folder).absolute()
    while not here.exists() and here != here.parent:
        here = here.parent
    if here.is_dir() and not os.access(here, os.W_OK | os.X_OK):
        fail(f"cannot write to {folder}: {here} is not writable (choose another folder with {flag})")


@contextmanager
def no_empty_folder(folder: Path):
    """Remove ``folder`` again if it did not exist before the block, the block failed and left it empty
    (a run refused before its first file must not leave an empty output folder behind)."""
    existed = folder.exists()
    ok = False
    try:
        yield
        ok = True
    except typer.Exit as e:
        ok = e.exit_code == 0
        raise
    finally:
        if not ok and not existed and folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def check_training_paths(data, resume, out) -> None:
    """The checks every ``cuboids train`` command makes of its DATA folder, ``--resume`` and ``--output``."""
    if not data.is_dir():
        fail(f"dataset folder not found: {data}")
    if resume is not None and not resume.is_file():
        fail(f"--resume {resume}: no such checkpoint (give OUT/last.pt)")
    if out.exists() and not out.is_dir():
        fail(f"--output {out} is a file; give a folder")


@contextmanager
def training_run(out: Path, resume: Path | None, first_save: str = "the first epoch ended"):
    """The block of a ``cuboids train`` command that runs its trainer, writing into ``out``: input errors
    and a ValueError end it with one line and exit status 2, leaving no empty ``out`` behind; Ctrl-C ends it
    with exit status 130 and the ``--resume`` that continues the run (OUT/last.pt once the trainer has
    saved one, else the ``resume`` it started from; nothing to resume before ``first_save``)."""
    with user_errors(), no_empty_folder(out):
        try:
            yield
        except ValueError as e:
            fail(str(e))
        except KeyboardInterrupt:
            last = out / "last.pt"
            if last.is_file():
                fail(f"interrupted; continue with --resume {last}", code=130)
            if resume is not None:
                fail(f"interrupted; continue with --resume {resume}", code=130)
            fail(f"interrupted before {first_save}; nothing to resume", code=130)


def progress_bar(label: str, *columns, **settings) -> Progress:
    """A progress bar on stderr: the text column ``label`` (a format such as ``"{task.description}"``), the
    bar and done/total, then ``columns`` (rich columns; a string is a text column's format); ``settings``
    go to :class:`~rich.progress.Progress` (``transient``, ``disable``)."""
    more = (TextColumn(c) if isinstance(c, str) else c for c in columns)
    return Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), *more, console=console, **settings)


def run_as_module(command, argv: list[str] | None, prog: str, prepare=None) -> None:
    """Run one command function as a program of its own (the ``python -m cuboidcli....`` entry points):
    ``argv`` None means the process's arguments; ``prepare`` turns the click command made of the function
    into the one that runs (the table of options applied to it). Returns when it succeeds, else exits with
    its status."""
    quiet_libraries()
    app = typer.Typer(add_completion=False)
    app.command()(command)
    program = typer.main.get_command(app)
    if prepare is not None:
        program = prepare(program)
    try:
        program.main(args=sys.argv[1:] if argv is None else list(argv), prog_name=prog)
    except SystemExit as e:
        if e.code not in (0, None):
            raise


def resolve_device(device: str) -> str:
    """A ``--device`` value resolved (:func:`cuboidcli.fitting.config.resolve_device`); one line and exit
    status 2 when it cannot be used."""
    from cuboidcli.fitting.config import resolve_device as resolve

    try:
        return resolve(device, "--device")
    except ValueError as e:
        fail(str(e))
