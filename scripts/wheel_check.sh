#!/usr/bin/env bash
# The wheel is the product: build it from this checkout, install it into a fresh virtual environment in a
# temporary folder outside the checkout, and run the commands a new user runs first (`cuboids demo`, a fit
# of a depth map with the learned sampler and the neural solver, the ONNX solver, and RGB-only input).
# Usage: scripts/wheel_check.sh   (PYTHON=python3.11 to pick the interpreter; KEEP=1 keeps the folder)
set -euo pipefail
PYTHON="${PYTHON:-python3}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
TMP="$(mktemp -d -t cuboids-wheel-XXXXXX)"
if [ "${KEEP:-0}" = "1" ]; then echo "keeping $TMP"; else trap 'rm -rf "$TMP"' EXIT; fi
SAMPLE="$ROOT/cuboidcli/data/sample"

echo "== building the wheel"
rm -rf "$ROOT/build"  # a stale build/lib would leak removed files into the wheel
"$PYTHON" -m pip wheel "$ROOT" --no-deps -q -w "$TMP/dist"
rm -rf "$ROOT/build"
WHEEL="$(ls "$TMP"/dist/cuboids-*.whl)"
echo "$(basename "$WHEEL"): $(du -h "$WHEEL" | cut -f1)"

echo "== installing it into a fresh venv in $TMP"
"$PYTHON" -m venv "$TMP/venv"
# torch first, pinned: an unpinned torch would pull the CUDA build (several GB).
"$TMP/venv/bin/pip" install -q "torch==2.13.0"
"$TMP/venv/bin/pip" install -q "$WHEEL" "torch==2.13.0"

cd "$TMP"  # outside the checkout: nothing may be read from it but the input files below
unset CUBOIDS_MODELS CUBOIDS_SOLVER_WEIGHTS CUBOIDS_SAMPLER_WEIGHTS CUBOIDS_DEPTH_WEIGHTS  # the shipped weights
run() { echo "\$ $*"; "$@"; }
run venv/bin/python -c "import cuboidcli, sys; sys.exit('imported from the checkout' if '$ROOT' in cuboidcli.__file__ else 0)"
run venv/bin/cuboids --version
run venv/bin/cuboids demo -o demo
test -s demo/sample_cuboids.json && test -s demo/sample_cuboids.glb
cp "$SAMPLE/sample_depth.png" d.png
cp "$SAMPLE/sample.png" rgb.png
run venv/bin/cuboids fit --depth d.png --camera nyu --sampler learned --solver neural --hypotheses 512 -o n.json -q
run venv/bin/cuboids export --onnx s.onnx
run venv/bin/cuboids fit --depth d.png --camera nyu --solver onnx --onnx s.onnx --hypotheses 512 -o o.json -q
run venv/bin/cuboids fit rgb.png -K 518.86,519.47,325.58,253.74 --hypotheses 512 -o r.json -q
# A photo without any camera information: its camera from its lines, else the default field of view (a warning).
run venv/bin/cuboids fit rgb.png --hypotheses 512 -o p.json -q
# A Hugging Face model without the hf extra: one line naming the extra, exit 2, nothing written.
set +e
venv/bin/cuboids fit rgb.png --depth-model hf:depth-anything/Depth-Anything-V2-Metric-Indoor-Small-hf -o h.json -q \
  > h.out 2>&1
rc=$?
set -e
cat h.out
test "$rc" = 2 && grep -q "cuboids\[hf\]" h.out && test ! -e h.json
# A whole room: a point cloud of a floor and four walls, written as a PLY with Open3D, fitted in its frame.
venv/bin/python - <<'PY'
import numpy as np
import open3d as o3d

rng = np.random.default_rng(0)
def plane(o, e1, e2, n):
    uv = rng.uniform(0, 1, (n, 2))
    return np.asarray(o) + uv[:, :1] * np.asarray(e1) + uv[:, 1:] * np.asarray(e2)
pts = np.concatenate([
    plane([0, 0, 0], [4, 0, 0], [0, 3, 0], 8000), plane([0, 0, 0], [4, 0, 0], [0, 0, 2.5], 4000),
    plane([0, 3, 0], [4, 0, 0], [0, 0, 2.5], 4000), plane([0, 0, 0], [0, 3, 0], [0, 0, 2.5], 3000),
    plane([4, 0, 0], [0, 3, 0], [0, 0, 2.5], 3000),
])
o3d.io.write_point_cloud("room.ply", o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)))
PY
run venv/bin/cuboids fit room.ply --voxel 0.1 -o room.json --glb -q
test -s room.glb
venv/bin/python - <<'PY'
import json

d = json.load(open("room.json"))
kinds = [c["kind"] for c in d["cuboids"]]
assert d["frame"] == "world" and "floor" in kinds and kinds.count("wall") >= 3, kinds
print(f"room.json: {len(kinds)} cuboids in the world frame: {', '.join(kinds)}")
PY
venv/bin/python - <<'PY'
import json

assert json.load(open("p.json"))["input"]["intrinsics_source"].startswith(("default:", "photo lines"))

for name in ("n.json", "o.json", "r.json"):
    d = json.load(open(name))
    assert d["schema"] == "cuboids/1" and d["cuboids"], f"{name}: no cuboids"
    print(f"{name}: {len(d['cuboids'])} cuboids ({d['settings']['sampler']}, {d['settings']['solver']})")
PY
echo "wheel check passed"
