"""Compare estimator variants (proposal schemes, samplers, hypothesis counts) on real frames and on a
synthetic split, and print one markdown table per data set.

    python scripts/eval_proposals.py --real ../shared/data/nyu ../shared/data/tum \\
        --synthetic runs/synth --split test --limit 20 --out runs/eval_proposals \\
        --variant "global:sampler=sequential,local_fraction=0,max_batches=1" \\
        --variant "mixed:sampler=sequential,local_fraction=0.75"

A variant is NAME:FIELD=VALUE,... with FitConfig fields (numbers, true/false, radii as 0.15/0.3/0.6).
Every variant is evaluated with :func:`cuboidcli.evaluation.runner.evaluate` on every data set; the real
folders are pooled into one data set. Writes OUT/results.json and OUT/tables.md; progress on stderr.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

from cuboidcli.evaluation.runner import EvalSettings, evaluate, load_frames
from cuboidcli.fitting.config import FitConfig
from cuboidcli.io.atomic import atomic_write_text

KEYS = (
    ("cuboids", "\\|M\\|", "{:.2f}"),
    ("coverage_pct", "coverage %", "{:.1f}"),
    ("oa_covered_cm", "OA cov. cm", "{:.1f}"),
    ("auc20cm_pct", "AUC@20 %", "{:.1f}"),
    ("auc5cm_pct", "AUC@5 %", "{:.1f}"),
    ("object_recall_pct", "obj. recall %", "{:.1f}"),
    ("object_precision_pct", "obj. prec. %", "{:.1f}"),
    ("slabs_within_3deg_pct", "slabs ≤3° %", "{:.1f}"),
    ("room_slabs_within_3deg_pct", "room slabs ≤3° %", "{:.1f}"),
    ("support_median_pct", "support %", "{:.1f}"),
    ("time_s", "time s", "{:.2f}"),
)


def parse_variant(text: str) -> tuple[str, dict]:
    name, _, spec = text.partition(":")
    types = {f.name: f.type for f in fields(FitConfig)}
    out: dict = {}
    for item in filter(None, spec.split(",")):
        key, _, value = item.partition("=")
        if key not in types:
            raise SystemExit(f"variant {name!r}: unknown FitConfig field {key!r}")
        t = str(types[key])
        if "tuple" in t:
            out[key] = tuple(float(v) for v in value.split("/"))
        elif "bool" in t:
            out[key] = value.lower() in ("1", "true", "yes")
        elif "int" in t:
            out[key] = int(value)
        elif "float" in t:
            out[key] = None if value == "none" else float(value)
        else:
            out[key] = value
    return name, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", type=Path, nargs="*", default=[], help="folders of real frames (pooled)")
    ap.add_argument("--synthetic", type=Path, help="synthetic dataset folder")
    ap.add_argument("--split", default="test")
    ap.add_argument("--limit", type=int, default=20)
    ap.add_argument("--variant", action="append", required=True, help="NAME:FIELD=VALUE,...")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument(
        "--weights", type=Path, default=None, help="weights of the learned sampler (.pt or folder)"
    )
    args = ap.parse_args()

    datasets = []
    if args.real:
        frames = []
        for folder in args.real:
            frames += load_frames(folder)[0]
        datasets.append(("real", frames))
    if args.synthetic:
        datasets.append(("synthetic", load_frames(args.synthetic, args.split, limit=args.limit)[0]))
    variants = [parse_variant(v) for v in args.variant]
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict = {"command": shlex.join(sys.argv), "variants": dict(variants), "results": {}}
    for data_name, frames in datasets:
        for name, overrides in variants:
            config = replace(FitConfig(), **overrides)
            t = time.perf_counter()
            report = evaluate(
                frames, config, EvalSettings(runs=args.runs, seed=args.seed, weights_dir=args.weights)
            )
            summary = {k: v[0] for k, v in report.summary.items() if isinstance(v, tuple)}
            parsimony = report.summary.get("parsimony")
            results["results"].setdefault(data_name, {})[name] = {"summary": summary, "parsimony": parsimony}
            print(
                f"{data_name:9s} {name:24s} "
                + " ".join(f"{k}={summary.get(k, float('nan')):.2f}" for k, _, _ in KEYS if k in summary)
                + f" ({time.perf_counter() - t:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
            atomic_write_text(args.out / "results.json", json.dumps(results, indent=1, default=str))
    lines = [f"`{results['command']}`", ""]
    for data_name, rows in results["results"].items():
        keys = [k for k in KEYS if any(k[0] in r["summary"] for r in rows.values())]
        lines += [f"### {data_name}", "", "| variant | " + " | ".join(h for _, h, _ in keys) + " |"]
        lines.append("|---" * (len(keys) + 1) + "|")
        for name, r in rows.items():
            cells = [fmt.format(r["summary"][k]) if k in r["summary"] else "" for k, _, fmt in keys]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    atomic_write_text(args.out / "tables.md", "\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
