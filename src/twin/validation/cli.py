"""``twin heldout``: the command of the held-out validation (:mod:`twin.validation.heldout`).

``cli.py`` wires it in with ``add_parser(sub)``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

DEFAULT_FILE = "validation/heldout.toml"


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``heldout`` command to the ``twin`` command's subparsers."""
    p = subparsers.add_parser(
        "heldout",
        help="identify testers as built on the calibration runs, judge the error model on held-out scenarios",
    )
    p.add_argument("file", nargs="?", help=f"held-out file (default: scenarios/{DEFAULT_FILE})")
    p.add_argument("--testers", type=int, metavar="N", help="number of testers (default: the file's)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: sweeps/heldout)")
    p.add_argument(
        "--scheduler", metavar="ADDR", help="an existing Dask scheduler (default: a local cluster)"
    )
    p.add_argument("--workers", type=int, metavar="N", help="local cluster size (default: one per core)")
    p.add_argument("--resume", action="store_true", help="run only the testers the output folder lacks")
    p.add_argument("--quiet", action="store_true", help="print only the last line")
    p.set_defaults(func=command)
    return p


def command(args: argparse.Namespace) -> int:
    """Run the held-out validation; exit code 0 (goals missed are figures, not errors)."""
    from twin.config.load import scenarios_dir
    from twin.errors import ConfigError
    from twin.validation.heldout import load_heldout, run_heldout

    if args.testers is not None and args.testers < 1:
        raise ConfigError("expected at least one tester", source="--testers")
    if args.workers is not None and args.workers < 1:
        raise ConfigError("expected at least one worker", source="--workers")
    cfg = load_heldout(Path(args.file) if args.file else scenarios_dir() / DEFAULT_FILE, testers=args.testers)
    from twin.outputs.run_folder import output_folder

    out = output_folder(args.out, Path("sweeps") / "heldout")
    echo = (lambda _: None) if args.quiet else print
    summary = run_heldout(
        cfg, out, scheduler=args.scheduler, workers=args.workers, resume=args.resume, echo=echo
    )
    for line in report_lines(summary):
        echo(line)
    print(f"heldout: {summary['testers']} testers, outputs in {out}")
    return 0


def report_lines(summary: dict[str, Any]) -> list[str]:
    """The figures and goals, one line each."""
    lines = []
    for model, m in summary["models"].items():
        a, th = m["all"], m["thermal_only"]
        if not a.get("rows"):
            lines.append(f"{model}: no row")
            continue
        thermal = f"{th['largest_residual_um']:.2f} um" if th.get("rows") else "no thermal-only row"
        lines.append(
            f"{model}: % of RMS removed median {a['removed_pct_median']:.1f}, 10th percentile "
            f"{a['removed_pct_p10']:.1f}; largest residual {a['largest_residual_um']:.2f} um; "
            f"thermal-only largest {thermal}"
        )
    for goal, g in summary["goals"].items():
        parts = ", ".join(
            f"{m} {v['value']:.2f} ({'met' if v['met'] else 'not met'})"
            for m, v in g.items()
            if isinstance(v, dict) and v.get("value") is not None
        )
        lines.append(f"goal {goal} {g['goal']}: {parts}")
    return lines
