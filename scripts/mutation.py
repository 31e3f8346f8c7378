"""Mutation testing of the core numerics: does the test suite notice when the code is wrong?

A small AST mutator (no third-party tool): each mutant changes ONE operator, comparison, constant or
min/max-like call in a target (see TARGETS), and the tests chosen for that target run against it. A mutant
is *killed* when a test fails (or the run times out), and *survives* when every test passes. The score is
killed / all. Survivors are listed with their line so that each is either killed by a new test or
explained as equivalent (docs/mutation.md).

The work happens in a throw-away copy of the repository (the working tree is never modified), one mutant
at a time, each test run with ``pytest -x`` in a worker process that reloads the package and the tests for
every mutant (torch and numba stay loaded; a timeout or a crash restarts it). Not part of CI: run it with
``scripts/mutation.sh``.

    python scripts/mutation.py [--only kernels,metrics] [--timeout 120] [--list]
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Target:
    name: str
    path: str
    """File to mutate, relative to the repository root."""
    functions: tuple[str, ...] | None
    """Only the bodies of these top-level functions / methods (None: the whole module)."""
    tests: tuple[str, ...]
    """pytest arguments that should kill its mutants, fastest first."""
    env: tuple[tuple[str, str], ...] = ()
    """Environment variables of the test process (NUMBA_DISABLE_JIT=1: numba kernels run as Python, so a
    mutant costs no compilation; their tests must then keep math.exp's arguments finite)."""


TARGETS = (
    Target(
        "kernels",
        "cuboidcli/geometry/kernels.py",
        None,
        (
            "tests/geometry/test_kernels.py",
            "tests/test_paper_defaults.py",
            "tests/test_properties.py",
            "tests/geometry/test_fused.py",
        ),
    ),
    Target(
        "pca_init",
        "cuboidcli/solvers/numerical.py",
        ("pca_init",),
        ("tests/solvers/test_solver_numerical.py",),
    ),
    *(
        Target(
            name,
            f"cuboidcli/evaluation/{name}.py",
            None,
            (
                "tests/evaluation/test_metrics_edges.py",
                "tests/evaluation/test_metrics.py",
                "tests/evaluation/test_eval_objects.py",
                "tests/evaluation/test_evaluate_failures.py",
            ),
        )
        for name in ("metrics", "auc", "aggregate", "object_recall")
    ),
    *(
        Target(
            name,
            f"cuboidcli/fitting/{name}.py",
            None,
            (
                "tests/fitting/test_backend.py",
                "tests/fitting/test_scoring.py",
                "tests/geometry/test_fused.py",
                "tests/fitting/test_pipeline.py",
                "tests/learn/test_seed_sampler.py",
            ),
        )
        for name in ("backend", "scoring", "refine")
    ),
    # the depth models users bring: ONNX files, Hugging Face checkpoints, and the scale/shift fit of a
    # relative prediction to metres
    *(
        Target(
            f"depth_{name}",
            f"cuboidcli/depth/{name}.py",
            None,
            (
                "tests/depth/test_scale_edges.py",
                "tests/depth/test_onnx_edges.py",
                "tests/depth/test_hf_edges.py",
                "tests/depth/test_hostile_models.py",
                "tests/depth/test_onnx_presets.py",
                "tests/depth/test_hf_depth.py",
                "tests/depth/test_depth_scale.py",
                "tests/depth/test_depth_estimator.py",
            ),
        )
        for name in ("onnx", "hf", "scale")
    ),
    # the camera and the down direction from a photo's own lines: segments, vanishing points (the
    # Manhattan frame and the focal search), their confidences, and the choice between the lines' down
    # direction and the depth's (test_lines_more for the segments' filters, test_vp_step for one step of
    # the refinement and the profile's use of it). test_photo_lines (the same estimate through load_frame,
    # 2-3 s a mutant) only for down.py, whose rule it applies; its plain-wall test is left out (30 s of
    # fallbacks)
    *(
        Target(
            name,
            f"cuboidcli/geometry/{name}.py",
            None,
            (
                *(
                    ("tests/geometry/test_down.py",)
                    if name == "down"
                    else (
                        *{
                            "lines": ("tests/geometry/test_lines_more.py",),
                            "vp_model": ("tests/geometry/test_vp_step.py",),
                            "manhattan_vp": ("tests/geometry/test_vp_step.py",),
                        }.get(name, ()),
                        "tests/geometry/test_vp_more.py",
                        "tests/geometry/test_vp_edges.py",
                    )
                ),
                "tests/geometry/test_vanishing.py",
                *(
                    (
                        "tests/load/test_photo_lines.py",
                        "--deselect",
                        "tests/load/test_photo_lines.py::test_a_photo_of_a_plain_wall_falls_back_with_one_warning",
                    )
                    if name == "down"
                    else ("tests/geometry/test_down.py",)
                ),
            ),
        )
        for name in ("lines", "vp_model", "manhattan_vp", "vanishing", "down")
    ),  # a room before it is fitted: the scan or sequence read and checked (units, extent), a sequence fused,
    # the cloud's voxels, normals and up direction, and the neighbourhood graph the objects are grown on
    Target(
        "room_load",
        "cuboidcli/load/room.py",
        None,
        ("tests/load/test_room_load_edges.py", "tests/load/test_load.py", "tests/load/test_units.py"),
    ),
    Target(
        "units",
        "cuboidcli/load/units.py",
        None,
        ("tests/load/test_units_edges.py", "tests/load/test_units.py"),
    ),
    Target(
        "fuse", "cuboidcli/load/fuse.py", None, ("tests/load/test_fuse_edges.py", "tests/io/test_sequence.py")
    ),
    Target(
        "cloud",
        "cuboidcli/geometry/cloud.py",
        None,
        (
            "tests/geometry/test_cloud_more.py",
            "tests/geometry/test_cloud_scores.py",
            "tests/geometry/test_free_side.py",
            "tests/geometry/test_cloud.py",
            "tests/geometry/test_camera_view.py",
            "tests/geometry/test_up_real.py",
        ),
    ),
    Target(
        "free_side",
        "cuboidcli/geometry/free_side.py",
        None,
        ("tests/geometry/test_free_side.py", "tests/geometry/test_cloud_more.py"),
    ),
    Target("consensus", "cuboidcli/fitting/consensus.py", None, ("tests/fitting/test_consensus.py",)),
    Target(
        "graph",
        "cuboidcli/geometry/graph.py",
        None,
        ("tests/geometry/test_graph_edges.py", "tests/geometry/test_graph.py"),
    ),
    # the room's shell (floor, walls, ceiling) told from what lies beyond a slab, and each box's kind
    Target(
        "shell",
        "cuboidcli/fitting/shell.py",
        None,
        (
            "tests/fitting/test_shell_edges.py",
            "tests/fitting/test_room_slabs.py",
            "tests/fitting/test_kinds.py",
        ),
    ),
    # the room scoring kernels, run as Python: compiling them for every mutant would take 20-30 s each, and
    # tests/geometry/test_room_scoring.py cannot run without numba (its far points overflow Python's math.exp)
    *(
        Target(name, path, None, ("tests/geometry/test_room_kernels.py",), (("NUMBA_DISABLE_JIT", "1"),))
        for name, path in (
            ("room_kernels", "cuboidcli/geometry/room.py"),
            ("room_value", "cuboidcli/geometry/room_value.py"),
            ("room_refine", "cuboidcli/geometry/room_refine.py"),
        )
    ),
    # a fitted room's whole objects: its points grouped into objects, their upright boxes and scores, and
    # the wall pieces and floor patches left out
    *(
        Target(
            name,
            f"cuboidcli/fitting/{name}.py",
            None,
            (
                "tests/fitting/test_objects.py",
                "tests/fitting/test_objects_edges.py",
                "tests/fitting/test_high_up.py",
                "tests/fitting/test_door_panel.py",
                "tests/fitting/test_nested.py",
            ),
        )
        for name in ("objects", "not_objects", "floors")
    ),
    # the sinks set into a counter's top, seats side by side under one back, and nested groups joined
    Target("basins", "cuboidcli/fitting/basins.py", None, ("tests/fitting/test_basins.py",)),
    Target("seats", "cuboidcli/fitting/seats.py", None, ("tests/fitting/test_seats.py",)),
    Target("nested", "cuboidcli/fitting/nested.py", None, ("tests/fitting/test_nested.py",)),
    Target("doors", "cuboidcli/fitting/doors.py", None, ("tests/fitting/test_doors.py",)),
    Target("door_leaves", "cuboidcli/fitting/door_leaves.py", None, ("tests/fitting/test_door_leaves.py",)),
    # a room's outline from above, and the share of a box beyond it
    Target("plan", "cuboidcli/geometry/plan.py", None, ("tests/geometry/test_plan.py",)),
    # the rules that change a fitted room's kinds: low walls are furniture, boxes beyond the outline walls,
    # low level slabs floor
    Target(
        "room_rules",
        "cuboidcli/fitting/room.py",
        ("low_walls_are_furniture", "beyond_the_room_is_wall", "low_slabs_are_floor"),
        ("tests/fitting/test_room_fit.py", "-k", "slab or wall or beyond"),
    ),
)

#: Operator swaps: each binary operator / comparison / boolean operator to its "most wrong" neighbour.
BINOPS = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.FloorDiv: ast.Div,
    ast.Pow: ast.Mult,
    ast.Mod: ast.FloorDiv,
    ast.MatMult: ast.Mult,
}
CMPOPS = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
}
#: Calls and attributes whose meaning flips with a sibling's.
NAMES = {
    "min": "max",
    "max": "min",
    "amin": "amax",
    "amax": "amin",
    "minimum": "maximum",
    "maximum": "minimum",
    "clamp_min": "clamp_max",
    "clamp_max": "clamp_min",
    "argmax": "argmin",
    "argmin": "argmax",
    "any": "all",
    "all": "any",
    "sum": "mean",
    "mean": "sum",
    "abs": "square",
    "sqrt": "square",
    "square": "abs",
}


@dataclass(frozen=True)
class Mutant:
    target: str
    index: int
    """Position of the mutated node in ``ast.walk`` order of the module."""
    line: int
    description: str


def _ranges(tree: ast.Module, functions: tuple[str, ...] | None) -> list[tuple[int, int]]:
    if functions is None:
        return [(1, 10**9)]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.name in functions:
            out.append((node.lineno, node.end_lineno or node.lineno))
    if not out:
        raise SystemExit(f"none of the functions {functions} found")
    return out


def _skipped_lines(tree: ast.Module) -> set[int]:
    """Lines not worth mutating: docstrings, imports, annotations, raise statements (their messages)."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
            value = body[0].value
            if isinstance(value, ast.Constant) and isinstance(value.value, str):
                skip.update(range(body[0].lineno, (body[0].end_lineno or body[0].lineno) + 1))
        if isinstance(node, ast.Import | ast.ImportFrom | ast.Raise):
            skip.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return skip


def _annotation_nodes(tree: ast.Module) -> set[int]:
    ids: set[int] = set()
    for node in ast.walk(tree):
        for ann in (getattr(node, "annotation", None), getattr(node, "returns", None)):
            if ann is not None:
                ids.update(id(n) for n in ast.walk(ann))
    return ids


def _describe(node: ast.AST) -> list[str]:
    """The mutations of one node, as descriptions (empty: nothing to mutate)."""
    if isinstance(node, ast.BinOp) and type(node.op) in BINOPS:
        return [f"{type(node.op).__name__} -> {BINOPS[type(node.op)].__name__}"]
    if isinstance(node, ast.Compare) and type(node.ops[0]) in CMPOPS:
        return [f"{type(node.ops[0]).__name__} -> {CMPOPS[type(node.ops[0])].__name__}"]
    if isinstance(node, ast.BoolOp):
        return ["and -> or" if isinstance(node.op, ast.And) else "or -> and"]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.Not):
        return ["drop unary " + type(node.op).__name__]
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return [f"{node.value!r} -> {_new_constant(node.value)!r}"]
    if isinstance(node, ast.Constant) and isinstance(node.value, bool):
        return [f"{node.value} -> {not node.value}"]
    if isinstance(node, ast.Attribute) and node.attr in NAMES:
        return [f".{node.attr} -> .{NAMES[node.attr]}"]
    if isinstance(node, ast.Name) and node.id in ("min", "max", "any", "all"):
        return [f"{node.id} -> {NAMES[node.id]}"]
    return []


def _new_constant(v):
    if v == 0:
        return 1
    if v == 1:
        return 2 if isinstance(v, int) else 0.5
    return v + 1 if isinstance(v, int) else v * 1.5


def _apply(node: ast.AST) -> None:
    if isinstance(node, ast.BinOp):
        node.op = BINOPS[type(node.op)]()
    elif isinstance(node, ast.Compare):
        node.ops[0] = CMPOPS[type(node.ops[0])]()
    elif isinstance(node, ast.BoolOp):
        node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
    elif isinstance(node, ast.Constant):
        node.value = (not node.value) if isinstance(node.value, bool) else _new_constant(node.value)
    elif isinstance(node, ast.Attribute):
        node.attr = NAMES[node.attr]
    elif isinstance(node, ast.Name):
        node.id = NAMES[node.id]


class _DropUnary(ast.NodeTransformer):
    def __init__(self, target: ast.AST) -> None:
        self.target = target

    def visit_UnaryOp(self, node: ast.UnaryOp):  # noqa: N802 - ast.NodeTransformer's naming
        self.generic_visit(node)
        return node.operand if node is self.target else node


def mutants(target: Target, source: str) -> list[Mutant]:
    tree = ast.parse(source)
    ranges = _ranges(tree, target.functions)
    skip = _skipped_lines(tree)
    annotations = _annotation_nodes(tree)
    out = []
    for i, node in enumerate(ast.walk(tree)):
        line = getattr(node, "lineno", None)
        if line is None or line in skip or id(node) in annotations:
            continue
        if not any(lo <= line <= hi for lo, hi in ranges):
            continue
        out += [Mutant(target.name, i, line, d) for d in _describe(node)]
    return out


def mutated_source(source: str, mutant: Mutant) -> str:
    tree = ast.parse(source)
    node = list(ast.walk(tree))[mutant.index]
    if isinstance(node, ast.UnaryOp):
        tree = _DropUnary(node).visit(tree)
    else:
        _apply(node)
    return ast.unparse(ast.fix_missing_locations(tree))


#: The test process: imports torch, numpy and numba once, then runs pytest in-process for each mutant after
#: dropping every module of the package and of the tests (so the mutated file is imported afresh). Saves the
#: interpreter and library start-up (about 4 s) per mutant. It answers each request with one "@@rc N" line.
WORKER = r"""
import json, sys
import numba, numpy, pytest, torch  # noqa: F401 - loaded once for every mutant
for line in sys.stdin:
    for name in [m for m in sys.modules if m.split(".")[0] in ("cuboidcli", "tests")]:
        del sys.modules[name]
    rc = pytest.main(json.loads(line))
    sys.stdout.write(f"\n@@rc {int(rc)}\n")
    sys.stdout.flush()
"""


class TestRunner:
    """A worker process in the repository copy that runs pytest on request (see WORKER)."""

    def __init__(self, repo: Path) -> None:
        self.repo = repo
        self.proc: subprocess.Popen | None = None
        self.lines: queue.Queue[str] = queue.Queue()
        self.env: tuple[tuple[str, str], ...] = ()

    def _start(self) -> subprocess.Popen:
        env = {**os.environ, **dict(self.env), "PYTHONPATH": str(self.repo), "PYTHONDONTWRITEBYTECODE": "1"}
        proc = subprocess.Popen(
            [sys.executable, "-c", WORKER],
            cwd=self.repo,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        self.lines = queue.Queue()
        # a reader thread: the test output is read line by line without blocking the timeout
        threading.Thread(target=self._read, args=(proc, self.lines), daemon=True).start()
        return proc

    @staticmethod
    def _read(proc: subprocess.Popen, lines: queue.Queue) -> None:
        for line in proc.stdout:
            lines.put(line)
        lines.put("")  # end of output: the worker exited

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None

    def run(
        self, tests: tuple[str, ...], timeout: float, env: tuple[tuple[str, str], ...] = ()
    ) -> tuple[bool, float]:
        """(the tests pass, seconds). A timeout or a crashed worker counts as failing tests. ``env``: extra
        environment variables of the worker (a new worker when they change)."""
        if env != self.env:
            self.stop()
            self.env = env
        if self.proc is None or self.proc.poll() is not None:
            self.proc = self._start()
        args = ["-x", "-q", "-p", "no:cacheprovider", "--no-header", *tests]
        t0 = time.perf_counter()
        self.proc.stdin.write(json.dumps(args) + "\n")
        self.proc.stdin.flush()
        while True:
            try:
                line = self.lines.get(timeout=max(timeout - (time.perf_counter() - t0), 0.01))
            except queue.Empty:  # timed out: an endless loop is a detected mutant too
                self.stop()
                return False, time.perf_counter() - t0
            if not line:  # the worker died (a crash in native code)
                self.stop()
                return False, time.perf_counter() - t0
            if line.startswith("@@rc "):
                return int(line.split()[1]) == 0, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", help="comma-separated target names: " + ", ".join(t.name for t in TARGETS))
    p.add_argument("--timeout", type=float, default=180.0, help="seconds per mutant's test run (killed)")
    p.add_argument("--list", action="store_true", help="list the mutants and exit")
    args = p.parse_args(argv)
    wanted = set(args.only.split(",")) if args.only else {t.name for t in TARGETS}
    targets = [t for t in TARGETS if t.name in wanted]
    work = Path(tempfile.mkdtemp(prefix="cuboids-mutation-"))
    try:
        ignore = shutil.ignore_patterns(".git", ".venv", "__pycache__", "*.pyc", "runs", ".pytest_cache")
        shutil.copytree(ROOT, work / "repo", ignore=ignore)
        repo = work / "repo"
        runner = TestRunner(repo)
        survivors: list[Mutant] = []
        total = killed = 0
        for target in targets:
            path = repo / target.path
            original = path.read_text(encoding="utf-8")
            ok, seconds = runner.run(target.tests, args.timeout * 3, target.env)
            if not ok:
                print(f"{target.name}: the tests fail on the unmutated code; fix them first", flush=True)
                return 2
            found = mutants(target, original)
            print(f"{target.name}: {len(found)} mutants of {target.path} ({seconds:.0f} s clean)", flush=True)
            for m in found:
                if args.list:
                    print(f"  {target.path}:{m.line}: {m.description}")
                    continue
                path.write_text(mutated_source(original, m), encoding="utf-8")
                try:
                    survived, seconds = runner.run(target.tests, args.timeout, target.env)
                finally:
                    path.write_text(original, encoding="utf-8")
                total += 1
                killed += not survived
                if survived:
                    survivors.append(m)
                status = "SURVIVED" if survived else "killed"
                print(f"  {status:8} {target.path}:{m.line}: {m.description} ({seconds:.0f} s)", flush=True)
        if args.list:
            return 0
        score = 100.0 * killed / total if total else 100.0
        print(f"\nmutation score: {killed}/{total} killed = {score:.1f} %")
        print(f"surviving mutants ({len(survivors)}):")
        lines = {}
        for t in targets:
            lines[t.name] = (repo / t.path).read_text(encoding="utf-8").splitlines()
        for m in survivors:
            target = next(t for t in targets if t.name == m.target)
            code = lines[m.target][m.line - 1].strip()
            print(f"  {target.path}:{m.line}: {m.description}    | {code}")
        return 0
    finally:
        if "runner" in locals():
            runner.stop()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
