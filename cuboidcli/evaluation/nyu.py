"""NYU Depth v2 in its official format: ``nyu_depth_v2_labeled.mat`` plus ``splits.mat``.

The labelled file is MATLAB v7.3, i.e. HDF5 with a 512-byte MATLAB header; h5py reads it directly (no
MATLAB re-save). MATLAB stores arrays column-major, so h5py sees them transposed: ``depths`` is (N, W, H)
float32 metres (in-painted, dense) and ``images`` (N, 3, W, H) uint8. ``splits.mat`` is an older MATLAB v5
file holding the 1-based column vectors ``testNdxs`` (654) and ``trainNdxs`` (795); we read it with the
small v5 reader below (SciPy is not a dependency), and also accept a v7.3 (HDF5) ``splits.mat``.

Splits as in the paper: test = the 654 testNdxs; train = the first 600 trainNdxs; val = the other 195.
Frames are named ``nyu_0001`` ... by their 1-based index in the labelled file.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError

LABELED = "nyu_depth_v2_labeled.mat"
SPLITS = "splits.mat"
SPLIT_NAMES = ("test", "train", "val")
N_TRAIN = 600  # the first 600 trainNdxs train, the remaining 195 validate (paper Sec. 4)

# MAT v5 data types (MATLAB "Level 5 MAT-file format") and numeric array classes.
_MI_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8", 12: "i8", 13: "u8"}
_MI_MATRIX, _MI_COMPRESSED = 14, 15
_CLASS_DTYPES = {
    6: "f8",
    7: "f4",
    8: "i1",
    9: "u1",
    10: "i2",
    11: "u2",
    12: "i4",
    13: "u4",
    14: "i8",
    15: "u8",
}


def _element(buf: bytes, pos: int, endian: str) -> tuple[int, bytes, int]:
    """One data element at ``pos``: (type, payload, position of the next element)."""
    first = struct.unpack_from(endian + "I", buf, pos)[0]
    if first >> 16:  # small data element: 2-byte size, 2-byte type, 4 bytes of payload
        nbytes, mtype = first >> 16, first & 0xFFFF
        return mtype, buf[pos + 4 : pos + 4 + nbytes], pos + 8
    mtype, nbytes = struct.unpack_from(endian + "II", buf, pos)
    end = pos + 8 + nbytes
    if end > len(buf):
        raise ValueError("truncated data element")
    return mtype, buf[pos + 8 : end], end + ((-nbytes) % 8 if mtype != _MI_COMPRESSED else 0)


def _matrix(payload: bytes, endian: str) -> tuple[str, np.ndarray | None]:
    """(name, array) of a miMATRIX payload; the array is None for non-numeric classes (cells, structs...)."""
    _, flags, pos = _element(payload, 0, endian)
    array_class = np.frombuffer(flags[:4], dtype=endian + "u4")[0] & 0xFF
    _, dims, pos = _element(payload, pos, endian)
    _, name, pos = _element(payload, pos, endian)
    shape = tuple(int(d) for d in np.frombuffer(dims, dtype=endian + "i4"))
    if array_class not in _CLASS_DTYPES:
        return name.decode("latin-1"), None
    mtype, real, _ = _element(payload, pos, endian)
    values = np.frombuffer(real, dtype=endian + _MI_DTYPES[mtype]).astype(_CLASS_DTYPES[array_class])
    return name.decode("latin-1"), values.reshape(shape, order="F")


def read_mat_v5(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Numeric arrays of a MATLAB v5/v7 (non-HDF5) .mat file, compressed or not, by variable name."""
    buf = Path(path).read_bytes()
    if len(buf) < 128 or buf[126:128] not in (b"IM", b"MI"):
        raise InputError(f"{path} is not a MATLAB v5 .mat file")
    endian = "<" if buf[126:128] == b"IM" else ">"
    out, pos = {}, 128
    while pos + 8 <= len(buf):
        mtype, payload, pos = _element(buf, pos, endian)
        if mtype == _MI_COMPRESSED:
            payload = zlib.decompress(payload)
            mtype, payload, _ = _element(payload, 0, endian)
        if mtype == _MI_MATRIX:
            name, array = _matrix(payload, endian)
            if array is not None:
                out[name] = array
    return out


def _read_mat_any(path: Path) -> dict[str, np.ndarray]:
    import h5py

    if h5py.is_hdf5(path):
        with h5py.File(path, "r") as f:
            return {k: np.asarray(f[k]) for k in f if isinstance(f[k], h5py.Dataset)}
    return read_mat_v5(path)


def read_splits(path: str | os.PathLike) -> dict[str, list[int]]:
    """0-based frame indices of the paper's test / train / val splits from the official ``splits.mat``."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"NYU split file not found: {path} (the official splits.mat)")
    try:
        arrays = _read_mat_any(path)
    except (ValueError, OSError, zlib.error) as e:
        raise InputError(f"cannot read {path}: {e}") from e
    missing = [k for k in ("testNdxs", "trainNdxs") if k not in arrays]
    if missing:
        raise InputError(f"{path} lacks {', '.join(missing)}; pass the official NYU Depth v2 splits.mat")
    test = [int(i) - 1 for i in arrays["testNdxs"].ravel()]
    train_all = [int(i) - 1 for i in arrays["trainNdxs"].ravel()]
    return {"test": test, "train": train_all[:N_TRAIN], "val": train_all[N_TRAIN:]}


@dataclass(frozen=True)
class NyuFrame:
    """One frame of the labelled file; the depth map is read on demand (picklable for worker processes)."""

    name: str
    mat_path: Path
    index: int
    """0-based index into the labelled file."""
    camera: Camera

    def depth_m(self) -> np.ndarray:
        """In-painted depth (H, W) float32 metres."""
        import h5py

        with h5py.File(self.mat_path, "r") as f:
            return np.ascontiguousarray(f["depths"][self.index].T, dtype=np.float32)

    def rgb(self) -> np.ndarray:
        """Colour image (H, W, 3) uint8."""
        import h5py

        with h5py.File(self.mat_path, "r") as f:
            return np.ascontiguousarray(f["images"][self.index].transpose(2, 1, 0))

    def gt_cuboids(self):
        return None


def is_nyu_folder(path: str | os.PathLike) -> bool:
    p = Path(path)
    return (p / LABELED).is_file() if p.is_dir() else p.name == LABELED


def list_nyu_frames(path: str | os.PathLike, split: str | None = "test") -> list[NyuFrame]:
    """Frames of a folder holding ``nyu_depth_v2_labeled.mat`` and ``splits.mat`` (or the .mat itself).

    ``split`` is test, train, val or None (all labelled frames, no splits.mat needed).
    """
    import h5py

    p = Path(path)
    mat = p / LABELED if p.is_dir() else p
    if not mat.is_file():
        raise InputError(f"{LABELED} not found in {p}")
    try:
        with h5py.File(mat, "r") as f:
            if "depths" not in f:
                raise InputError(f"{mat} has no 'depths' array; is it the NYU Depth v2 labelled file?")
            n, width, height = f["depths"].shape
    except OSError as e:
        raise InputError(f"cannot open {mat} as MATLAB v7.3/HDF5: {e}") from e
    camera = Camera.preset("nyu").with_size(width, height)
    if split is None:
        indices = list(range(n))
    else:
        if split not in SPLIT_NAMES:
            raise InputError(f"--split {split}: NYU has the splits {', '.join(SPLIT_NAMES)}")
        indices = read_splits(mat.parent / SPLITS)[split]
        bad = [i for i in indices if not 0 <= i < n]
        if bad:
            raise InputError(f"{SPLITS} refers to frame {bad[0] + 1} but {mat.name} holds only {n} frames")
    return [NyuFrame(f"nyu_{i + 1:04d}", mat, i, camera) for i in indices]
