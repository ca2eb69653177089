"""``studio evaluate PRED GT [--radius M] [--frame base|odom] [--max-range M] [--json OUT]``: metrics and JSON
(DESIGN §2)."""

from __future__ import annotations

import argparse
import json

from studio.atomic import out_file, write_out
from studio.errors import StudioError

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    from studio.evaluate import evaluate

    radius = float(args.radius)
    if not radius > 0:
        raise StudioError(f"--radius must be a positive number of metres, got {radius}")
    if args.max_range is not None and args.frame != "base":
        raise StudioError("--max-range is measured in the base frame: use it without --frame odom")
    out = out_file(args.json, "--json", inputs=[args.pred, args.gt])
    ev = evaluate(args.pred, args.gt, radius=radius, frame=args.frame, max_range=args.max_range)
    where = "" if args.frame == "base" else " (positions in the odom frame)"
    print(f"studio evaluate: {args.pred} vs ground truth {args.gt}{where}")
    print(ev.table())
    if out is not None:
        write_out(out, json.dumps(ev.to_json(), indent=2, allow_nan=False) + "\n", "--json")
        print(f"metrics written to {out}")
    return 0
