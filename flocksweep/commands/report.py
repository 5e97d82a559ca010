"""``flocksweep report``: statistics, figures and tested claims from a results directory."""
from __future__ import annotations

import sys
from pathlib import Path

from flocksweep.command import Command
from flocksweep.sweeps.failures import check_count, check_out

HELP = "statistics, figures and tested claims from a results directory"
DESCRIPTION = ("Write a self-contained HTML report, the same as Markdown with figures, and the tables behind it as "
               "CSV (default: RESULTS_DIR/report/).")


def arguments(p) -> None:
    p.add_argument("dir", type=Path, help="results directory of a sweep (with runs.parquet)")
    p.add_argument("--metrics", nargs="+", metavar="NAME",
                   help="metrics (default: cohesion alignment stray_fraction groups elongation speed); "
                        "names like cohesion or columns like cohesion_final")
    p.add_argument("--by", nargs="+", metavar="FACTOR", help="factors to analyse (default: all swept factors)")
    p.add_argument("--out", type=Path, help="output directory (default RESULTS_DIR/report)")
    p.add_argument("--format", choices=("html", "md", "both"), default="both",
                   help="html: report.html (self-contained); md: report.md with its figures as PNG files; "
                        "both (default)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the bootstrap resampling and of the claims' power simulations (default 0)")
    p.add_argument("--claims", nargs="+", type=Path, default=[], metavar="FILE",
                   help="also test the claims of these claims files (or sweep files), e.g. configs/claims/holland.toml")
    p.add_argument("--no-progress", action="store_true", help="no progress lines (each section as it starts) on stderr")


def handler(args) -> int:
    from flocksweep.analysis.reports.report import ReportError, build_report
    from flocksweep.sweeps.progress import next_steps

    formats = ("html", "md") if args.format == "both" else (args.format,)
    check_out("--out", args.out)
    check_count("--seed", args.seed, 0, 2 ** 63 - 1)
    try:
        result = build_report(args.dir, args.out, args.metrics, args.by, formats, args.seed, args.claims,
                              progress=not args.no_progress)
    except (ReportError, FileNotFoundError) as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    for kind, path in result["paths"].items():
        print(f"  wrote {path}")
    print(f"  tables: {result['out'] / 'tables'} ({len(result['tables'])} CSV files); {result['seconds']:.1f} s")
    claims = result["tables"].get("claims")
    for row in (claims.itertuples() if claims is not None else ()):
        print(f"  claim ({row.claim}): {row.verdict}: {row.statement}")
    next_steps(*after_report(args.dir, result, claims))
    return 0


def after_report(results_dir: Path, result: dict, claims) -> list[str]:
    """Open the page; and, when a claim is undecided for lack of power, the run that adds replicates."""
    page = result["paths"].get("html") or result["paths"].get("md")
    steps = [f"open {page} in a browser (self-contained: figures, tables and claims in one file)"]
    if claims is not None and (claims["verdict"] == "inconclusive").any():
        steps.append(f"flocksweep run {Path(results_dir) / 'sweep.toml'} --until-claims --max-replicates 20"
                     f"   (more replicates where a claim is undecided)")
    return steps


COMMAND = Command("report", HELP, DESCRIPTION, arguments, handler)
