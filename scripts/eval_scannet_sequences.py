"""Fit real ScanNet-style scans as posed RGB-D sequences and score them on the part the views see.

Each scan's coloured points are rendered into N views from a loop of cameras inside the room and written
as a TUM folder (cuboidcli/evaluation/scannet_views.py); the folder is fitted as ``cuboids fit FOLDER``
fits it, and the result is scored as scripts/eval_scannet.py scores a scan (cuboidcli/evaluation/
scannet.py), with the labelled boxes restricted to those the views see (at least half of the instance's
points) and the points (AUC, precision) to the seen ones.

    python scripts/eval_scannet_sequences.py ../shared/data/scannet --json scannet_sequences.json
    python scripts/eval_scannet_sequences.py ../shared/data/scannet --scans scene0001_00 --keep /tmp/seq

Scans are rendered (a few seconds) and fitted (about half a minute on a 2-core CPU) one after the other.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from cuboidcli.evaluation.scannet import (
    class_recall,
    pool_rows,
    read_truth,
    scan_fit,
    scan_metrics,
    scan_names,
)
from cuboidcli.evaluation.scannet_report import markdown_header
from cuboidcli.evaluation.scannet_report import markdown_line as table_line
from cuboidcli.evaluation.scannet_views import VIEWS, render_scan, scan_colors
from cuboidcli.evaluation.scene_run import json_safe


def evaluate_scan(fitter, folder: Path, name: str, out: Path, views: int, size: tuple[int, int]) -> dict:
    """Render scan ``name`` into ``out`` and fit and score it: its row, with the render's figures."""
    truth = read_truth(folder, name)
    t = time.perf_counter()
    rendered = render_scan(truth, scan_colors(folder, name), out, views, *size)
    render_s = time.perf_counter() - t
    t = time.perf_counter()
    result = fitter.fit(str(rendered.folder))
    fit = scan_fit(result.record.to_json(), time.perf_counter() - t)
    row = scan_metrics(fit, rendered.truth)
    row.update(
        views=views,
        render_seconds=render_s,
        seen_points_pct=100.0 * float(rendered.seen.mean()),
        seen_boxes=len(rendered.truth.boxes),
        all_boxes=len(truth.boxes),
    )
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "folder", type=Path, help="a folder of scans: NAME_vert.npy or NAME.ply, NAME_bbox.npy, ..."
    )
    ap.add_argument("--scans", nargs="*", help="the scans to fit (default: every scan of the folder)")
    ap.add_argument("--views", type=int, default=VIEWS, help="views rendered per scan")
    ap.add_argument("--size", type=int, nargs=2, default=(320, 240), metavar=("W", "H"), help="image size")
    ap.add_argument(
        "--keep", type=Path, help="write the sequences under this folder (default: a temp folder)"
    )
    ap.add_argument("--json", type=Path, help="write the rows and the pooled row here")
    ap.add_argument("--seed", type=int, default=0, help="the fit's seed")
    ap.add_argument(
        "--tune",
        nargs="*",
        default=["scene0001", "scene0002", "scene0003"],
        help="scan-name prefixes of the scenes constants are chosen on: pooled rows for them and the rest",
    )
    args = ap.parse_args()
    names = args.scans or scan_names(args.folder)
    if not names:
        ap.error(f"no scans in {args.folder} (NAME_bbox.npy with NAME.ply or NAME_vert.npy)")
    missing = sorted(set(names) - set(scan_names(args.folder)))
    if missing:
        ap.error(f"not scans of {args.folder}: {', '.join(missing)}")
    if args.views < 1:
        ap.error("--views must be at least 1")

    import cuboidcli

    fitter = cuboidcli.Fitter(seed=args.seed)
    header, rule = markdown_header()  # the scan evaluation's table, with what the views saw added
    print(header + " seen pts % | seen boxes | render s |")
    print(rule + "---|" * 3, flush=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="cuboids-scannet-views-") as tmp:
        base = args.keep if args.keep is not None else Path(tmp)
        for name in names:
            row = evaluate_scan(fitter, args.folder, name, base / name, args.views, tuple(args.size))
            rows.append(row)
            extra = f" {row['seen_points_pct']:.1f} | {row['seen_boxes']}/{row['all_boxes']} | "
            print(table_line(row) + extra + f"{row['render_seconds']:.1f} |", flush=True)
    pooled = pool_rows(rows)
    print(table_line(pooled))
    prefixes = tuple(args.tune or ())
    tune = [r for r in rows if prefixes and r["scan"].startswith(prefixes)]
    rest = [r for r in rows if not (prefixes and r["scan"].startswith(prefixes))]
    for label, part in (("tuning scenes", tune), ("other scenes", rest)):
        if part and len(part) < len(rows):
            print(table_line({**pool_rows(part), "scan": f"pooled, {label}"}))
    print(f"\n{pooled['capped']} of {len(rows)} scans stopped at the cuboid cap")
    print("\nrecall at IoU 0.25 by class (pooled, seen boxes): " + ", ".join(
        f"{name} {m}/{n}" for name, (m, n) in class_recall(pooled).items()
    ))  # fmt: skip
    if args.json:
        doc = {"version": cuboidcli.__version__, "folder": str(args.folder), "seed": args.seed}
        doc.update(views=args.views, size=list(args.size))
        doc["settings"] = {"fit": fitter.config.for_kind("room").to_dict()}  # as `cuboids evaluate` does
        doc.update(scans=rows, pooled=pooled)
        args.json.write_text(json.dumps(json_safe(doc), indent=1))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
