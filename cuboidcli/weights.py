"""The weights registry: which file each network loads. Everything that picks weights asks here.

- **The table**: :data:`NETWORKS`, one record per kind of network: its shipped default, the environment
  variable that replaces it, the names it has in a weights folder and who loads it. :data:`KINDS`,
  :data:`FILES`, :data:`SOLVER_FILES`, :data:`DEFAULTS`, :data:`ENV` and :data:`DEFAULT_FILES` are views
  of it. Which sampler or solver loads which kind is the parts registry's
  (:data:`cuboidcli.fitting.parts.PARTS`).
- **Shipped weights**: :data:`MODELS_DIR`, the repository's ``models/`` (``cuboidcli/models`` in an
  installed wheel, see setup.py), ``$CUBOIDS_MODELS`` overriding it; :func:`shipped_path` finds a path the
  documentation writes (``models/solver_v1.pt``) there.
- **Defaults**: :func:`default_path` per network kind, with the environment overrides :data:`ENV`
  (``$CUBOIDS_SAMPLER_WEIGHTS``, ``$CUBOIDS_SOLVER_WEIGHTS``, ``$CUBOIDS_DEPTH_WEIGHTS``).
- **Resolution**: :func:`resolve` turns a weights value (None, a folder, a file) into the file a network
  loads; :func:`weights_for` and :func:`check_weights_option` route one ``--weights`` value to the networks
  of a run by what a file holds (:func:`checkpoint_kind`); :func:`files_loaded` lists what a run loads.
- **Bundles**: the learned parts are trained as sets: the sampling-weight network with the numerical solver
  on true depth (``models/``), fine-tuned together with the neural solver (``models/neural/``), or
  fine-tuned from RGB with the built-in depth network (``models/rgb/``, opt-in: see
  :func:`default_depth_weights`). Each bundle is a folder in the ``--weights DIR`` layout. When the user
  gives no ``--weights``, :func:`default_weights_dir` picks the bundle that matches the configuration; a
  bundle that is not there falls back to the top-level ``models/`` files.
- **Hashes**: :func:`short_hash` and :func:`describe_weights` (the default files with their SHA-256).

The network modules themselves are in :mod:`cuboidcli.nets`, the file reader in
:mod:`cuboidcli.io.checkpoints`.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from cuboidcli.fitting import parts


@dataclass(frozen=True)
class Network:
    """One kind of network and its files."""

    kind: str
    """``sampler``, ``solver`` or ``depth``, as :func:`cuboidcli.io.checkpoints.checkpoint_kind` tells them
    apart."""
    default: str
    """The shipped default weights, relative to :data:`MODELS_DIR`."""
    env: str
    """The environment variable that replaces :attr:`default`."""
    folder_files: tuple[str, ...]
    """Its names in a weights folder, the first found is loaded; the first is the one the trainers write
    (a fine-tuned bundle holds ``depth_v2.pt``, while the shipped default depth network is a later one)."""
    bundle: str | None = None
    """The folder of MODELS_DIR its users load every network of the fit from when no ``--weights`` is
    given (the set it was fine-tuned with); None: the top-level defaults."""
    used_by: str | None = None
    """Who loads it, as ``cuboids --version`` says; None: the parts that load it (``--solver neural``)."""

    def users(self) -> str:
        return self.used_by or " / ".join(p.flag for p in parts.loading(self.kind))


#: Every kind of network, the sampler's and the solver's first (the networks a fit loads).
NETWORKS: tuple[Network, ...] = (
    Network("sampler", "sampler_v2.pt", "CUBOIDS_SAMPLER_WEIGHTS", ("sampler_v2.pt",)),
    Network("solver", "solver_v2.pt", "CUBOIDS_SOLVER_WEIGHTS", ("solver_v2.pt", "solver_v1.pt"), "neural"),
    Network("depth", "depth_v4.pt", "CUBOIDS_DEPTH_WEIGHTS", ("depth_v2.pt",),
            used_by="RGB input (depth network)"),
)  # fmt: skip
NETWORK = {n.kind: n for n in NETWORKS}

#: The kinds of network, as :func:`cuboidcli.io.checkpoints.checkpoint_kind` tells them apart.
KINDS = tuple(NETWORK)
#: File name of each network in a weights folder (what the trainers write).
FILES = {n.kind: n.folder_files[0] for n in NETWORKS}
#: Solver files looked for in a folder, first found: ``solver_v1.pt`` in folders of the first release.
SOLVER_FILES = NETWORK["solver"].folder_files
#: The environment variable that replaces each network's default weights file.
ENV = {n.kind: n.env for n in NETWORKS}
#: Each network's default weights file, relative to MODELS_DIR.
DEFAULTS = {n.kind: n.default for n in NETWORKS}
#: The kinds of network a fit loads (those its samplers and solvers load), in NETWORKS order.
FIT_KINDS = tuple(k for k in KINDS if parts.loading(k))
#: The bundle fine-tuned from RGB with the built-in depth network; opt-in while it holds no sampler.
RGB_BUNDLE = "rgb"


def _default_files() -> tuple[tuple[str, str], ...]:
    """(who loads it, path relative to MODELS_DIR) of every file a run loads when no weights are given:
    each network's default, or, where its users load a bundle, the bundle's file of every network a fit
    loads (the others labelled with their kind)."""
    rows = []
    for net in NETWORKS:
        if net.bundle is None:
            rows.append((net.users(), net.default))
            continue
        rows.append((net.users(), f"{net.bundle}/{FILES[net.kind]}"))
        rows += [(f"{net.users()} ({k})", f"{net.bundle}/{FILES[k]}") for k in FIT_KINDS if k != net.kind]
    return tuple(rows)


def _shipped_models_dir() -> Path:
    """Where the shipped weights are: ``cuboidcli/models`` in an installed wheel (the build copies the
    repository's ``models/`` there, see setup.py), else the top-level ``models/`` of a source checkout or an
    editable install."""
    here = Path(__file__).resolve().parent
    installed = here / "models"
    return installed if installed.is_dir() else here.parent / "models"


#: The shipped weights; ``$CUBOIDS_MODELS`` overrides them.
MODELS_DIR = Path(os.environ.get("CUBOIDS_MODELS") or _shipped_models_dir())

#: The files loaded when no weights are given: (what uses it, path relative to MODELS_DIR).
DEFAULT_FILES = _default_files()


def short_hash(path: Path, digits: int = 12) -> str:
    """The first ``digits`` hex digits of a file's SHA-256 (the model cards list the full ones)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:digits]


def describe_weights() -> list[str]:
    """Lines for ``cuboids --version``: the models folder and each default weights file with a short hash."""
    lines = [f"weights: {MODELS_DIR}" + ("  ($CUBOIDS_MODELS)" if os.environ.get("CUBOIDS_MODELS") else "")]
    for use, rel in DEFAULT_FILES:
        path = MODELS_DIR / rel
        state = f"sha256 {short_hash(path)}" if path.is_file() else "MISSING"
        lines.append(f"  {rel:<22} {state:<20} {use}")
    return lines


def shipped_path(value: str | os.PathLike) -> Path:
    """A weights path as the documentation writes it (``models/solver_v1.pt``), found in the shipped
    weights when it does not exist relative to the working directory (an installed package has no
    ``models/`` folder there). Any other path is returned as given."""
    path = Path(value)
    names = path.parts
    if path.exists() or path.is_absolute() or len(names) < 2 or names[0] != "models":
        return path
    shipped = MODELS_DIR.joinpath(*names[1:])
    return shipped if shipped.exists() else path


def depth_model_path(model: str | os.PathLike | None) -> str | None:
    """A ``--depth-model`` value as the depth factories take it: None (the built-in network) and a Hugging
    Face id (``hf:owner/name``) as written, a file or folder found with :func:`shipped_path`."""
    if model is None or str(model).startswith("hf:"):
        return None if model is None else str(model)
    return str(shipped_path(model))


def default_weights_dir(solver: str, rgb: bool = False, builtin_depth: bool = True) -> Path | None:
    """The bundle for a configuration, or None for the top-level defaults.

    ``rgb``: the depth comes from the image; ``builtin_depth``: through the built-in network (a user's depth
    model gets the depth-input sampler, which was not tuned for any particular network).
    """
    if rgb and builtin_depth and (MODELS_DIR / RGB_BUNDLE / FILES["sampler"]).is_file():
        return MODELS_DIR / RGB_BUNDLE
    net = NETWORK.get(parts.network_of("solver", solver))
    if net is not None and net.bundle is not None and (MODELS_DIR / net.bundle / FILES[net.kind]).is_file():
        return MODELS_DIR / net.bundle
    return None


def default_depth_weights() -> Path:
    """The built-in depth network's default weights: ``models/depth_v4.pt``.

    depth_v4 is depth_v3 (48 min on 960 synthetic rooms) trained 60 min more on 1,200 new rooms with a
    gradient-matching loss and photometric augmentation; from RGB it gives better cuboids on the real
    sample photos than depth_v3 (AUC@20 14.6 -> 17.1 %, coverage 68.7 -> 75.2 %; models/depth_v4.md).
    depth_v1, depth_v3 and the end-to-end fine-tuned ``models/rgb/depth_v2.pt`` stay available with
    ``--depth-model``.
    """
    return MODELS_DIR / DEFAULTS["depth"]


def default_path(kind: str) -> Path:
    """The default weights file of a network ``kind``: ``$CUBOIDS_<KIND>_WEIGHTS`` if set, else the shipped
    file (``models/sampler_v2.pt``, ``models/solver_v2.pt``, ``models/depth_v4.pt``)."""
    env = os.environ.get(ENV[kind])
    return Path(env) if env else MODELS_DIR / DEFAULTS[kind]


def resolve(kind: str, weights: str | os.PathLike | None = None) -> Path:
    """The file a network of ``kind`` loads for a weights value. None: :func:`default_path`. Otherwise, as
    each loader has always read it: sampler: a ``.pt`` file as given, any other path as a folder holding
    ``sampler_v2.pt``; solver: a folder's ``solver_v2.pt`` (``solver_v1.pt`` if only that is there), a file
    as given; depth: the path as given."""
    if weights is None:
        return default_path(kind)
    path = Path(weights)
    if kind == "sampler":
        return path if path.suffix == ".pt" else path / FILES["sampler"]
    if kind == "solver" and path.is_dir():
        named = [path / name for name in SOLVER_FILES]
        return next((p for p in named if p.is_file()), named[0])
    return path


def checkpoint_kind(path: str | os.PathLike) -> str | None:
    """ "sampler", "solver" or "depth" for a weights file of ours (by its config keys), else None.

    Remembered per file version (path, size, modification time): fit and evaluate ask once per network
    kind for the same ``--weights`` file, which is then read only once here.
    """
    st = Path(path).stat()
    return _checkpoint_kind(str(Path(path).resolve()), st.st_size, st.st_mtime_ns)


@lru_cache(maxsize=32)
def _checkpoint_kind(path: str, size: int, mtime_ns: int) -> str | None:
    from cuboidcli.io.checkpoints import CheckpointError, read_checkpoint
    from cuboidcli.io.checkpoints import checkpoint_kind as kind_of

    try:
        return kind_of(read_checkpoint(path))
    except CheckpointError:  # unreadable or refused: not one of ours (its loader says what is wrong)
        return None


def weights_for(kind: str, weights: str | os.PathLike | None) -> str | os.PathLike | None:
    """What a component of ``kind`` should load for a ``--weights`` value: a folder as given (each part
    picks its file in it), a ``.pt`` file if it holds this kind of network, else None (the shipped default:
    ``--weights solver.pt`` with the learned sampler keeps the shipped sampler)."""
    if weights is None or Path(weights).is_dir() or not Path(weights).is_file():
        return weights
    return weights if checkpoint_kind(weights) in (kind, None) else None


def networks_loaded(solver: str, sampler: str) -> list[str]:
    """The kinds of network a configuration loads from ``--weights``."""
    kinds = (parts.network_of("solver", solver), parts.network_of("sampler", sampler))
    return [kind for kind in dict.fromkeys(kinds) if kind is not None]


def files_loaded(solver: str, sampler: str, weights: str | os.PathLike | None = None) -> dict[str, Path]:
    """The weights file of each network a configuration loads for a ``--weights`` value (None: the
    defaults), by kind: ``{"solver": ..., "sampler": ...}``."""
    return {kind: resolve(kind, weights_for(kind, weights)) for kind in networks_loaded(solver, sampler)}


def check_weights_option(weights: str | os.PathLike | None, solver: str, sampler: str) -> None:
    """Refuse a ``--weights`` value that no part of the run would load (it would be silently ignored):
    any value when no part that loads a network runs (the neural solver, the learned sampler), or a file of
    ours that holds another network (a depth network, or the sampler with only ``--solver neural``). Raises
    :class:`~cuboidcli.io.checkpoints.CheckpointError`."""
    from cuboidcli.io.checkpoints import CheckpointError

    if weights is None:
        return
    kinds = networks_loaded(solver, sampler)
    if not kinds:
        loaders = (p.flag for kind in ("solver", "sampler") for p in parts.loading(kind))
        raise CheckpointError(
            f"--weights {weights}: this run loads no network; --weights applies to {' and '.join(loaders)}"
        )
    if Path(weights).is_file() and (found := checkpoint_kind(weights)) not in (*kinds, None):
        raise CheckpointError(
            f"--weights {weights} holds the {found} network, but this run loads the "
            f"{' and '.join(kinds)} network ({', '.join(NETWORK[k].users() for k in kinds)}); pass that "
            "file or a folder that holds it"
        )
