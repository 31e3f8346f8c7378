"""Fit real ScanNet-style scans with the default settings and score their whole objects against the
labelled furniture boxes (cuboidcli/evaluation/scannet.py: recall at IoU 0.25 / 0.5, precision, AP by
the objects' scores, per-class recall, AUC of the points' distances, cuboids, seconds).

    python scripts/eval_scannet.py ../shared/data/scannet --json scannet.json
    python scripts/eval_scannet.py ../shared/data/scannet --scans scene0001_00 scene0003_01

Scans are fitted one after the other; each takes about half a minute on a 2-core CPU. ``cuboids evaluate
FOLDER`` fits and scores the same way, with the fit options of the command line; this script adds the
pooled rows of the scenes the constants were tuned on and of the others (``--tune``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cuboidcli.evaluation.scannet import evaluate_scans, pool_rows, scan_names
from cuboidcli.evaluation.scannet_report import (
    markdown_header,
    markdown_line,
    summary_lines,
    write_scannet_report,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "folder", type=Path, help="a folder of scans: NAME.ply or NAME_vert.npy, NAME_bbox.npy, ..."
    )
    ap.add_argument("--scans", nargs="*", help="the scans to fit (default: every scan of the folder)")
    ap.add_argument("--json", type=Path, help="write the report here (as cuboids evaluate -o writes it)")
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

    print("\n".join(markdown_header()), flush=True)

    def progress(done: int, total: int, name: str, row: dict | None) -> None:
        if row is not None:
            print(markdown_line(row), flush=True)

    fitter = cuboidcli.Fitter(seed=args.seed)
    rows, pooled = evaluate_scans(args.folder, fitter, names, progress)
    print(markdown_line(pooled))
    prefixes = tuple(args.tune or ())
    tune = [r for r in rows if r["scan"].startswith(prefixes)] if prefixes else []
    rest = [r for r in rows if not (prefixes and r["scan"].startswith(prefixes))]
    for label, part in (("tuning scenes", tune), ("other scenes", rest)):
        if part and len(part) < len(rows):
            print(markdown_line({**pool_rows(part), "scan": f"pooled, {label}"}))
    print("\n" + "\n".join(summary_lines(pooled)))
    if args.json:
        provenance = {
            "command": " ".join(["python", *sys.argv]),
            "data": str(args.folder.resolve()),
            "seed": args.seed,
            "settings": {"fit": fitter.config.for_kind("room").to_dict()},
        }
        print(f"wrote {write_scannet_report(args.json, rows, pooled, provenance)}")


if __name__ == "__main__":
    main()
