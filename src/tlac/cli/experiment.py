"""``tlac experiment ...`` and ``tlac report ...``: the command-line side of the experiments.

The main ``tlac`` command calls :func:`register` to add these sub-commands; each parser sets
``func=handler(args) -> int`` (exit status). ``python -m tlac experiment ...`` runs them
standalone. Errors are :class:`~tlac.errors.TlacError`; the main CLI prints them as one line.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from tlac.argtypes import positive_int
from tlac.errors import TlacError, require_extra


def _experiment_run(args: argparse.Namespace) -> int:
    require_extra("experiments", "tlac experiment run", "rich")
    from tlac.experiments.config import load_config
    from tlac.experiments.runner import run_local, run_ray

    config = load_config(args.config)
    if args.backend == "ray":
        summary = run_ray(
            config, args.out, address=args.address, workers=args.workers, only=args.only
        )
    else:
        if args.address is not None:
            raise TlacError("--address needs --backend ray")
        summary = run_local(config, args.out, workers=args.workers or 1, only=args.only)
    for line in summary.lines():
        print(line)
    if summary.interrupted:
        print(f"interrupted: rerun the same command to resume ({args.out})")
        return 130
    return 0 if summary.ok else 1


def _experiment_list(args: argparse.Namespace) -> int:
    from tlac.experiments.config import load_config
    from tlac.experiments.grid import expand_grid
    from tlac.experiments.runner import grid_status, select_runs, with_recorded_domain

    config = load_config(args.config, import_domain=False)  # a domain file is never run here
    if args.out:
        config = with_recorded_domain(config, args.out)
    if config.domain_name is None:
        print(
            f"{config.name}: {config.domain}: not yet trained (its runs are named after the "
            "domain's own name, recorded by 'tlac experiment run'; listing does not import it)"
        )
        return 0
    rows = grid_status(config, args.out, args.only) if args.out else None
    runs = select_runs(expand_grid(config), args.only)
    print(
        f"{config.name}: {config.domain}, {len(config.teacher_sets)} teacher sets x "
        f"{len(config.algorithms)} algorithms, {len(runs)} runs of {config.steps:,} steps"
    )
    if rows is None:
        for r in runs:
            print(f"  {r.name}  teachers={r.spec.teachers}")
    else:
        for r, status in rows:
            print(f"  {status:<9} {r.name}")
    return 0


def _report(args: argparse.Namespace) -> int:
    require_extra("experiments", "tlac report", "pandas", "matplotlib")
    from tlac.experiments.report import write_report

    path = write_report(args.dir, paper=args.paper)
    print(f"wrote {path} and figures in {Path(path).parent / 'figures'}")
    return 0


ONLY_HELP = (
    "only the runs whose name matches one of these comma-separated shell patterns, e.g. "
    "'*__tlac__*' or '*3noisy*,*teacher-l*' (the others are left for another time or machine)"
)


def register(subparsers: Any) -> None:
    """Add ``experiment`` (``run``, ``list``) and ``report`` to the main CLI's sub-parsers."""
    exp = subparsers.add_parser("experiment", help="run a grid of runs declared in a YAML file")
    exp_sub = exp.add_subparsers(dest="experiment_command", required=True)

    run = exp_sub.add_parser(
        "run",
        help="run (or resume) every run of an experiment file",
        description="Runs every unfinished run of CONFIG into DIR/runs/<name>/. Rerunning the "
        "same command skips finished runs and redoes interrupted or failed ones.",
    )
    run.add_argument("config", help="experiment YAML file (see configs/ and docs/experiments.md)")
    run.add_argument("--out", required=True, metavar="DIR", help="output folder of the grid")
    run.add_argument(
        "--workers",
        type=positive_int,
        default=None,
        metavar="N",
        help="parallel runs (local: processes, default 1; ray: runs in flight, "
        "and the CPUs of a local Ray instance)",
    )
    run.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="local processes (default) or Ray tasks",
    )
    run.add_argument(
        "--address",
        default=None,
        metavar="ADDR",
        help="Ray cluster to join (auto, or HEAD:6379); default: start a local one",
    )
    run.add_argument("--only", default=None, metavar="PATTERNS", help=ONLY_HELP)
    run.set_defaults(func=_experiment_run)

    lst = exp_sub.add_parser("list", help="print the runs of an experiment file (and their status)")
    lst.add_argument("config")
    lst.add_argument("--out", default=None, metavar="DIR", help="show each run's status in DIR")
    lst.add_argument("--only", default=None, metavar="PATTERNS", help=ONLY_HELP)
    lst.set_defaults(func=_experiment_list)

    rep = subparsers.add_parser(
        "report",
        help="write a Markdown report and PNG figures for an experiment folder or a run folder",
        description="Reads DIR/experiment.yaml and DIR/runs/* (or DIR/runs.tar.xz, written by "
        "'tlac results pack'), or the one run of a run folder of 'tlac train' (its "
        "config.yaml), writes DIR/report.md, DIR/figures/*.png and DIR/summary.csv.",
    )
    rep.add_argument(
        "dir", metavar="DIR", help="output folder of 'tlac experiment run', or of 'tlac train'"
    )
    rep.add_argument(
        "--paper",
        action="store_true",
        help="show the paper's jumpstarts (Tables 1-3) beside ours where they exist",
    )
    rep.set_defaults(func=_report)
