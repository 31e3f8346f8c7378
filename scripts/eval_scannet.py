"""Fit real ScanNet-style scans with the default settings and score their whole objects against the
labelled furniture boxes (cuboidcli/evaluation/scannet.py: recall at IoU 0.25 / 0.5, precision, AP by
the objects' scores, per-class recall, AUC of the points' distances, cuboids, seconds).

    python scripts/eval_scannet.py ../shared/data/scannet --json scannet.json
    python scripts/eval_scannet.py ../shared/data/scannet --scans scene0001_00 scene0003_01

Scans are fitted one after the other; each takes about half a minute on a 2-core CPU.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from cuboidcli.evaluation.scannet import class_recall, evaluate_scans, pool_rows, scan_names
from cuboidcli.evaluation.scene_run import json_safe

#: Table columns: (row key, header, format).
COLUMNS = (
    ("scan", "scan", "{}"),
    ("labelled", "labelled", "{:.1f}"),
    ("objects", "objects", "{:.1f}"),
    ("recall_iou0.25_pct", "R@.25", "{:.1f}"),
    ("recall_iou0.5_pct", "R@.5", "{:.1f}"),
    ("precision_pct", "precision", "{:.1f}"),
    ("ap_iou0.25_pct", "AP@.25", "{:.1f}"),
    ("ap_iou0.5_pct", "AP@.5", "{:.1f}"),
    ("auc20cm_pct", "AUC@20", "{:.1f}"),
    ("auc5cm_pct", "AUC@5", "{:.1f}"),
    ("cuboids", "cuboids", "{:.1f}"),
    ("up_error_deg", "up err", "{:.2f}"),
    ("seconds", "s", "{:.1f}"),
)


def _cell(row: dict, key: str, fmt: str) -> str:
    v = row.get(key)
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return fmt.format(v)


def table_line(row: dict) -> str:
    return "| " + " | ".join(_cell(row, k, f) for k, _, f in COLUMNS) + " |"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "folder", type=Path, help="a folder of scans: NAME.ply or NAME_vert.npy, NAME_bbox.npy, ..."
    )
    ap.add_argument("--scans", nargs="*", help="the scans to fit (default: every scan of the folder)")
    ap.add_argument("--json", type=Path, help="write the rows and the pooled row here")
    ap.add_argument("--seed", type=int, default=0, help="the fit's seed")
    ap.add_argument(
        "--tune",
        nargs="*",
        default=["scene0001", "scene0002", "scene0003"],
        help="scan-name prefixes of the scenes constants are chosen on: pooled rows for them and the rest "
        "(rescans of one room stay on one side)",
    )
    args = ap.parse_args()
    names = args.scans or scan_names(args.folder)
    if not names:
        sys.exit(f"no scans in {args.folder} (NAME_bbox.npy with NAME.ply or NAME_vert.npy)")
    missing = sorted(set(names) - set(scan_names(args.folder)))
    if missing:
        sys.exit(f"not scans of {args.folder}: {', '.join(missing)}")

    import cuboidcli

    print("| " + " | ".join(h for _, h, _ in COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS), flush=True)
    rows, pooled = evaluate_scans(
        args.folder,
        cuboidcli.Fitter(seed=args.seed),
        names,
        lambda name, row: print(table_line(row), flush=True),
    )
    print(table_line(pooled))
    prefixes = tuple(args.tune or ())
    tune = [r for r in rows if r["scan"].startswith(prefixes)] if prefixes else []
    rest = [r for r in rows if not (prefixes and r["scan"].startswith(prefixes))]
    for label, part in (("tuning scenes", tune), ("other scenes", rest)):
        if part and len(part) < len(rows):
            print(table_line({**pool_rows(part), "scan": f"pooled, {label}"}))
    print(f"\n{pooled['capped']} of {len(rows)} scans stopped at the cuboid cap")
    print("\nrecall at IoU 0.25 by class (pooled): " + ", ".join(
        f"{name} {m}/{n}" for name, (m, n) in class_recall(pooled).items()
    ))  # fmt: skip
    if args.json:
        doc = {"version": cuboidcli.__version__, "folder": str(args.folder), "seed": args.seed}
        doc.update(scans=rows, pooled=pooled)
        args.json.write_text(json.dumps(json_safe(doc), indent=1))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
