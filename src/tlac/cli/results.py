"""``tlac results ...``: upkeep of experiment folders.

``tlac results pack DIR`` replaces the run folders ``DIR/runs/*`` by one compressed archive
``DIR/runs.tar.xz`` holding only the files the reports read
(:mod:`tlac.experiments.packing`); ``tlac report`` and ``tlac experiment`` read it directly.
"""

from __future__ import annotations

import argparse
from typing import Any


def _pack(args: argparse.Namespace) -> int:
    from tlac.experiments.packing import pack_study

    print(pack_study(args.dir).line())
    return 0


def register(subparsers: Any) -> None:
    """Add ``results`` (``pack``) to the main CLI's sub-parsers."""
    res = subparsers.add_parser("results", help="upkeep of experiment folders (pack their runs)")
    res_sub = res.add_subparsers(dest="results_command", required=True)
    pack = res_sub.add_parser(
        "pack",
        help="replace DIR/runs/ by one compressed archive DIR/runs.tar.xz",
        description="Puts every run folder DIR/runs/<name>/ into DIR/runs.tar.xz, keeping only "
        "the files the reports read (config.yaml, episodes.csv, eval.csv, teacher_usage.csv, "
        "result.json, error.txt: no model weights, no monitor.csv or progress.csv), then removes "
        "DIR/runs/. 'tlac report' and 'tlac experiment' read the archive directly. A study "
        "packed earlier and given new runs since is packed again by merging: the new archive "
        "holds both, a run folder winning over the archive's copy of the same run.",
    )
    pack.add_argument("dir", metavar="DIR", help="output folder of 'tlac experiment run'")
    pack.set_defaults(func=_pack)
