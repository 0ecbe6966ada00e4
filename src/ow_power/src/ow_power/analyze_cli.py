"""``rosrun ow_power analyze``: energy per operation from bags, as a table, PNG, CSV and JSON."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from ow_power.analysis import analyze, format_table, plot_power, write_summary
from ow_power.config import PowerConfig
from ow_power.errors import AnalysisError, ConfigError


def output_stem(first_bag: Path) -> str:
    """The run name of a bag, ``ow_2025-01-01-12-00-00`` for ``ow_2025-01-01-12-00-00_0003.bag``."""
    stem = first_bag.stem
    head, _, index = stem.rpartition("_")
    return head if head and index.isdigit() else stem


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; 0 on success, 1 when the bags cannot be analysed."""
    parser = argparse.ArgumentParser(
        prog="analyze",
        description="Energy and power per arm operation from bags recorded by `rosrun ow_power "
        "record` (a run split into several files: pass them all, or their directory).",
    )
    parser.add_argument("bags", nargs="+", type=Path, help="bag files or directories of bags")
    parser.add_argument(
        "-o",
        "--output-dir",
        type=Path,
        help="where the PNG, CSV and JSON go (default: the first bag's directory)",
    )
    parser.add_argument(
        "--recompute",
        action="store_true",
        help="compute power from /joint_states even when /power was recorded",
    )
    parser.add_argument(
        "--p0",
        type=float,
        default=PowerConfig.auxiliary_power_w,
        help="W, auxiliary power P0 when recomputing (default %(default)s)",
    )
    parser.add_argument(
        "--efficiency",
        type=float,
        default=PowerConfig.motor_efficiency,
        help="motor efficiency when recomputing (default %(default)s)",
    )
    parser.add_argument(
        "--max-dt",
        type=float,
        default=PowerConfig.max_dt_s,
        help="s, longest interval integrated (default %(default)s)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the PNG")
    args = parser.parse_args(argv)
    try:
        config = PowerConfig.from_dict(
            {
                "auxiliary_power_w": args.p0,
                "motor_efficiency": args.efficiency,
                "max_dt_s": args.max_dt,
            }
        )
        result = analyze(args.bags, recompute=args.recompute, config=config)
    except (AnalysisError, ConfigError) as exc:
        print(f"analyze: {exc}", file=sys.stderr)
        return 1
    out_dir = args.output_dir or result.bags[0].parent
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = out_dir / output_stem(result.bags[0])
    print(format_table(result))
    written = [
        stem.with_name(stem.name + "_operations.csv"),
        stem.with_name(stem.name + "_operations.json"),
    ]
    write_summary(result, *written)
    if not args.no_plot:
        png = stem.with_name(stem.name + "_power.png")
        plot_power(result, png)
        written.append(png)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


if __name__ == "__main__":
    sys.exit(main())
