"""``tlac teacher ...``: train a SAC teacher, measure teachers on their own.

The main command wires this in with ``tlac.cli.teacher.register(subparsers)``::

    tlac teacher train hopper-bullet --steps 1000000 --seed 0 --out src/tlac/data/teachers
    tlac teacher eval pickplace --teachers optimal,good,noisy --episodes 1000 --seed 0 --json

Each sub-command sets ``func(args) -> int`` (the exit status). Bad input raises
:class:`tlac.errors.ConfigError` / :class:`tlac.errors.UnknownNameError`, which the main CLI
prints as one line with exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from typing import Any

from tlac.argtypes import non_negative_int, positive_int
from tlac.errors import ConfigError


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``teacher`` command (with ``train`` and ``eval``) to ``subparsers``."""
    teacher = subparsers.add_parser(
        "teacher", help="train SAC teachers (Hopper) or measure any domain's teachers"
    )
    sub = teacher.add_subparsers(dest="teacher_command", metavar="{train,eval}")
    sub.required = True

    train = sub.add_parser(
        "train",
        help="train a SAC (Hopper) or PPO (DoorKey) teacher and export its actor "
        "(paper appendix A.1.1, A.2.1)",
        description="Train stable-baselines3 SAC on ENV, checkpointing every 10k steps "
        "(rerunning resumes from the checkpoint), then evaluate the deterministic actor "
        "and write <out>/<env>-sac.pt and <env>-sac.json.",
    )
    train.add_argument("env", help="hopper-bullet or hopper (SAC), doorkey (PPO)")
    train.add_argument("--steps", type=positive_int, default=1_000_000)
    train.add_argument("--seed", type=non_negative_int, default=0)
    train.add_argument("--out", default="src/tlac/data/teachers", help="where to write weights")
    train.add_argument(
        "--work-dir", default=None, help="checkpoint folder (default runs/teachers/<env>-seed<S>)"
    )
    train.add_argument(
        "--time-limit",
        type=float,
        default=None,
        help="stop training after this many seconds, then evaluate and export what was reached",
    )
    train.add_argument("--eval-episodes", type=positive_int, default=100)
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.add_argument(
        "--trust-pickle",
        action="store_true",
        help="continue from the SB3 checkpoint in --work-dir: its pickles can run code when "
        "loaded, so only for a checkpoint you made",
    )
    train.set_defaults(func=_train)

    ev = sub.add_parser(
        "eval",
        help="measure teachers alone: mean +- std return and success rate",
        description="Run each named teacher alone on ENV; episode i is reset with seed S+i.",
    )
    ev.add_argument("env", help="a domain name (doorkey, hopper-bullet, hopper, pickplace)")
    ev.add_argument("--teachers", default=None, help="comma-separated teacher names (default: all)")
    ev.add_argument("--episodes", type=positive_int, default=100)
    ev.add_argument("--seed", type=non_negative_int, default=0)
    ev.add_argument("--n-envs", type=positive_int, default=8)
    ev.add_argument("--json", action="store_true", help="print one JSON object")
    ev.set_defaults(func=_eval)
    return teacher


def _train(args: argparse.Namespace) -> int:
    from tlac.teacher_training import train_teacher

    if args.time_limit is not None and not 0 < args.time_limit < math.inf:  # NaN too
        raise ConfigError(
            f"--time-limit must be a finite number of seconds > 0, got {args.time_limit}"
        )
    # Record the command line as typed (from "train" on), for the metadata file.
    argv = sys.argv[1:]
    if "train" in argv:
        rest = argv[argv.index("train") + 1 :]
        command = "tlac teacher train " + " ".join(shlex.quote(a) for a in rest)
    else:  # called programmatically
        command = (
            f"tlac teacher train {args.env} --steps {args.steps} --seed {args.seed} "
            f"--out {args.out}"
        )
    train_teacher(
        args.env,
        args.steps,
        args.seed,
        args.out,
        progress_bar=not args.no_progress,
        work_dir=args.work_dir,
        eval_episodes=args.eval_episodes,
        time_limit_s=args.time_limit,
        command=command,
        trust_pickle=args.trust_pickle,
    )
    return 0


def _eval(args: argparse.Namespace) -> int:
    from tlac.domains import get_domain
    from tlac.errors import UnknownNameError
    from tlac.evaluation import measure_teacher

    domain = get_domain(args.env)
    names = (
        [n.strip() for n in args.teachers.split(",") if n.strip()]
        if args.teachers
        else list(domain.teacher_names)
    )
    if not names:
        raise ConfigError("--teachers is empty; give comma-separated teacher names")
    for name in names:
        if name not in domain.teacher_names:
            raise UnknownNameError(f"teacher for {domain.name}", name, domain.teacher_names)
    results: dict[str, Any] = {}
    for name in names:
        start = time.time()
        r = measure_teacher(domain, name, args.episodes, args.seed, n_envs=args.n_envs)
        r.pop("returns", None)
        r["wall_s"] = round(time.time() - start, 1)
        results[name] = r
        if not args.json:
            success = "" if r["success_rate"] is None else f"  success {r['success_rate']:.3f}"
            print(
                f"{domain.name:14s} {name:8s} {r['mean']:10.2f} +- {r['std']:8.2f} "
                f"over {r['episodes']} episodes{success}",
                flush=True,
            )
    if args.json:
        print(
            json.dumps(
                {
                    "env": domain.name,
                    "seed": args.seed,
                    "episodes": args.episodes,
                    "teachers": results,
                }
            )
        )
    return 0
