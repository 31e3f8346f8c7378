"""The README's evaluation matrix of the learned components: samplers x solvers on a synthetic test split
and on real frames, optionally from RGB through a depth network. Prints markdown tables.

    python scripts/eval_learned.py --synthetic DATA --split test --limit 20 \\
        --real ../shared/data/nyu ../shared/data/tum --out runs/eval_learned \\
        [--hypotheses 4096] [--weights-numerical DIR] [--weights-neural DIR] \\
        [--samplers uniform,sequential,learned] [--solvers numerical,neural] \\
        [--rgb --depth-model PATH --weights-rgb DIR [--depth-model-base PATH2] [--weights-rgb-base DIR2]]

Datasets: "synthetic" is DATA (a folder in the generic layout, or the official NYU files) with --split and
--limit; "real" is all frames of the --real folders together (--real-limit keeps the first frames of each
folder). Every configuration calls :func:`cuboidcli.evaluation.runner.evaluate` with
``FitConfig(hypotheses, sampler, solver, seed)`` and ``EvalSettings(weights_dir=W)``.

Weights (the runner's ``weights_dir``: a folder holding solver_v1.pt and/or sampler_v2.pt, or one .pt file;
None = the shipped defaults) are chosen by the SOLVER of a row: --weights-numerical for the numerical
solver, --weights-neural for the neural one. The uniform and sequential samplers ignore them; the neural
solver always loads solver_v1.pt from W, so with the learned sampler and the neural solver W must be a folder
holding both files.

--rgb adds rows that fit the depth predicted from each frame's RGB image (scored against the true depth):
learned sampler, numerical solver, --depth-model and --weights-rgb ("rgb" rows); with --depth-model-base
or --weights-rgb-base also the same before fine-tuning ("rgb base" rows; an option not given there means the
shipped default).

A configuration that cannot run (missing weights, frames without RGB, ...) is reported on stderr and left
out of the tables (listed under "skipped" in results.json). Progress: one line per configuration on stderr.

Writes OUT/results.json (all aggregates, per-frame rows, settings, weights hashes; rewritten atomically after
every configuration) and OUT/tables.md (the command line and the tables).
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path

COLUMNS = (
    ("sampler", None),
    ("solver", None),
    ("input", None),
    ("\\|M\\|", ("cuboids", "{:.2f}")),  # pipes escaped: a bare |M| would split the cell
    ("coverage %", ("coverage_pct", "{:.1f}")),
    ("OA covered cm", ("oa_covered_cm", "{:.2f}")),
    ("OA all cm", ("oa_all_cm", "{:.2f}")),
    ("AUC@20 %", ("auc20cm_pct", "{:.1f}")),
    ("AUC@5 %", ("auc5cm_pct", "{:.1f}")),
    ("time s/frame", ("time_s", "{:.2f}")),
)


@dataclass(frozen=True)
class Row:
    """One configuration of the matrix."""

    sampler: str
    solver: str
    input: str  # "depth", "rgb" or "rgb base"
    weights_dir: Path | None
    depth_model: Path | None = None

    @property
    def rgb(self) -> bool:
        return self.input != "depth"

    def label(self) -> str:
        if not self.rgb:
            return "depth"
        return f"{self.input} ({self.depth_model.name if self.depth_model else 'shipped depth net'})"


def csv_list(text: str, allowed: tuple[str, ...], flag: str) -> list[str]:
    items = [s.strip() for s in text.split(",") if s.strip()]
    bad = [s for s in items if s not in allowed]
    if bad or not items:
        raise argparse.ArgumentTypeError(f"{flag} {text!r}: choose from {', '.join(allowed)}")
    return items


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--synthetic", type=Path, help="synthetic dataset folder (generic layout)")
    ap.add_argument("--split", default="test", help="split of --synthetic (default test)")
    ap.add_argument("--limit", type=int, default=20, help="first N frames of --synthetic (default 20)")
    ap.add_argument(
        "--real", type=Path, nargs="+", default=[], help="real frame folders, evaluated as one set"
    )
    ap.add_argument("--real-limit", type=int, default=None, help="first N frames of each --real folder")
    ap.add_argument("--out", type=Path, required=True, help="output folder (results.json, tables.md)")
    ap.add_argument("--hypotheses", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grid-step", type=int, default=8, help="fitting grid step (4 for 320x240 frames)")
    ap.add_argument("--runs", type=int, default=1, help="seeds SEED..SEED+R-1; the tables show the means")
    ap.add_argument("--workers", type=int, default=1, help="frame-parallel processes (default 1)")
    ap.add_argument("--weights-numerical", type=Path, default=None, help="weights for numerical-solver rows")
    ap.add_argument("--weights-neural", type=Path, default=None, help="weights for neural-solver rows")
    ap.add_argument("--samplers", default="uniform,sequential,learned")
    ap.add_argument("--solvers", default="numerical,neural")
    ap.add_argument("--rgb", action="store_true", help="add the RGB rows (learned sampler, numerical solver)")
    ap.add_argument("--depth-model", type=Path, default=None, help="depth network of the rgb rows")
    ap.add_argument("--weights-rgb", type=Path, default=None, help="sampler weights of the rgb rows")
    ap.add_argument("--depth-model-base", type=Path, default=None, help="depth network of the rgb base rows")
    ap.add_argument(
        "--weights-rgb-base", type=Path, default=None, help="sampler weights of the rgb base rows"
    )
    args = ap.parse_args(argv)
    try:
        args.samplers = csv_list(args.samplers, ("uniform", "sequential", "local", "learned"), "--samplers")
        args.solvers = csv_list(args.solvers, ("numerical", "neural"), "--solvers")
    except argparse.ArgumentTypeError as e:
        ap.error(str(e))
    if args.synthetic is None and not args.real:
        ap.error("give --synthetic DATA and/or --real FOLDER ...")
    if not args.rgb and any(
        x is not None
        for x in (args.depth_model, args.weights_rgb, args.depth_model_base, args.weights_rgb_base)
    ):
        ap.error("--depth-model, --weights-rgb and their -base variants need --rgb")
    if args.hypotheses < 1 or args.limit < 1 or args.workers < 1:
        ap.error("--hypotheses, --limit and --workers must be positive")
    return args


def configurations(args: argparse.Namespace) -> list[Row]:
    rows = []
    for sampler in args.samplers:
        for solver in args.solvers:
            w = args.weights_numerical if solver == "numerical" else args.weights_neural
            rows.append(Row(sampler, solver, "depth", w))
    if args.rgb:
        rows.append(Row("learned", "numerical", "rgb", args.weights_rgb, args.depth_model))
        if args.depth_model_base is not None or args.weights_rgb_base is not None:
            rows.append(Row("learned", "numerical", "rgb base", args.weights_rgb_base, args.depth_model_base))
    return rows


def load_datasets(args: argparse.Namespace) -> dict[str, tuple[list, dict]]:
    """{name: (frames, description)}."""
    from cuboidcli.evaluation.runner import load_frames

    out = {}
    if args.synthetic is not None:
        out["synthetic"] = load_frames(args.synthetic, args.split, limit=args.limit)
    if args.real:
        frames, parts = [], []
        for folder in args.real:
            f, meta = load_frames(folder, limit=args.real_limit)
            frames.extend(f)
            parts.append(meta)
        names = [f.name for f in frames]
        if len(set(names)) != len(names):
            print("warning: frame names repeat across the --real folders", file=sys.stderr)
        out["real"] = (frames, {"folders": parts, "frames": names})
    return out


def jsonable(x):
    """Paths as strings, NaN/inf as None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, Path):
        return str(x)
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def fmt(value, spec: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return spec.format(value)


def markdown_table(results: list[dict]) -> str:
    lines = [
        "| " + " | ".join(name for name, _ in COLUMNS) + " |",
        "|" + "|".join("---" if key is None else "---:" for _, key in COLUMNS) + "|",
    ]
    for r in results:
        agg = r["aggregates"]
        cells = [r["sampler"], r["solver"], r["input_label"]]
        cells += [fmt(agg.get(key), spec) for _, (key, spec) in COLUMNS[3:]]
        lines.append("| " + " | ".join(cells) + " |")
    empty = [
        f"{r['sampler']}/{r['solver']}/{r['input_label']}: {r['aggregates']['frames_without_cuboids']}"
        for r in results
        if r["aggregates"].get("frames_without_cuboids")
    ]
    if empty:
        lines += [
            "",
            "Frames without any cuboid (left out of the OA means, zero recall in the AUC): "
            + "; ".join(empty),
        ]
    return "\n".join(lines)


def dataset_heading(name: str, desc: dict, n_frames: int) -> str:
    if name == "synthetic":
        where = f"{desc['path']}, split {desc['split']}"
    else:
        where = ", ".join(p["path"] for p in desc["folders"])
    return f"### {name}: {n_frames} frame{'s' if n_frames != 1 else ''} ({where})"


def write_outputs(out: Path, command: str, payload: dict, tables: str) -> None:
    from cuboidcli.io.atomic import atomic_write_json, atomic_write_text

    atomic_write_json(out / "results.json", jsonable(payload))
    atomic_write_text(out / "tables.md", f"```\n{command}\n```\n\n{tables}")


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    from cuboidcli.evaluation.provenance import machine_info
    from cuboidcli.evaluation.runner import EvalSettings, evaluate
    from cuboidcli.fitting.config import FitConfig
    from cuboidcli.io.depth import InputError

    command = shlex.join(sys.orig_argv if argv is None else [sys.executable, __file__, *argv])
    command += f"    # in {os.getcwd()}"
    datasets = load_datasets(args)
    rows = configurations(args)
    payload: dict = {
        "command": command,
        "machine": machine_info(),
        "args": {k: v for k, v in vars(args).items()},
        "datasets": {},
        "skipped": [],
    }
    tables: list[str] = []
    total = len(datasets) * len(rows)
    k = 0
    t_all = time.perf_counter()
    for ds_name, (frames, desc) in datasets.items():
        results: list[dict] = []
        payload["datasets"][ds_name] = {"description": desc, "results": results}
        for row in rows:
            k += 1
            tag = f"[{k}/{total}] {ds_name}: sampler {row.sampler}, solver {row.solver}, input {row.label()}"
            config = FitConfig(
                hypotheses=args.hypotheses,
                sampler=row.sampler,
                solver=row.solver,
                seed=args.seed,
                grid_step=args.grid_step,
            )
            settings = EvalSettings(
                runs=args.runs,
                seed=args.seed,
                workers=args.workers,
                weights_dir=row.weights_dir,
                rgb=row.rgb,
                depth_model=row.depth_model,
            )
            t = time.perf_counter()
            try:
                report = evaluate(frames, config, settings)
            except (FileNotFoundError, InputError) as e:
                msg = str(e).splitlines()[0] if str(e) else type(e).__name__
                print(f"{tag}: SKIPPED after {time.perf_counter() - t:.1f} s: {msg}", file=sys.stderr)
                payload["skipped"].append(
                    {"dataset": ds_name, **_row_dict(row), "error": f"{type(e).__name__}: {msg}"}
                )
                write_outputs(args.out, command, payload, "\n\n".join(tables))
                continue
            elapsed = time.perf_counter() - t
            agg = report.runs[0] if args.runs == 1 else {k: v[0] for k, v in report.summary.items()}
            print(
                f"{tag}: {elapsed:.1f} s ({len(frames)} frames; |M| {agg['cuboids']:.2f}, "
                f"AUC@20 {agg.get('auc20cm_pct', math.nan):.1f} %)",
                file=sys.stderr,
            )
            results.append(
                {
                    **_row_dict(row),
                    "input_label": row.label(),
                    "config": config.to_dict(),
                    "aggregates": agg,
                    "summary": report.summary,
                    "weights": report.weights,
                    "frames": [m.row() for m in report.frames[0]],
                    "wall_s": elapsed,
                }
            )
            write_outputs(args.out, command, payload, "\n\n".join(tables))
        if results:
            tables.append(dataset_heading(ds_name, desc, len(frames)) + "\n\n" + markdown_table(results))
        else:
            tables.append(dataset_heading(ds_name, desc, len(frames)) + "\n\n(no configuration ran)")
    skipped = payload["skipped"]
    if skipped:
        lines = [
            f"- {s['dataset']}: sampler {s['sampler']}, solver {s['solver']}, input {s['input']}: "
            f"{s['error']}"
            for s in skipped
        ]
        tables.append("Skipped:\n\n" + "\n".join(lines))
    text = "\n\n".join(tables) + "\n"
    write_outputs(args.out, command, payload, text)
    print(f"```\n{command}\n```\n\n{text}", end="")
    print(
        f"done: {total - len(skipped)}/{total} configurations in {time.perf_counter() - t_all:.1f} s; "
        f"wrote {args.out / 'results.json'} and {args.out / 'tables.md'}",
        file=sys.stderr,
    )


def _row_dict(row: Row) -> dict:
    return {
        "sampler": row.sampler,
        "solver": row.solver,
        "input": row.input,
        "weights_dir": row.weights_dir,
        "depth_model": row.depth_model,
    }


if __name__ == "__main__":
    main()
