"""``tlac teach ENV``: train with a person as a teacher through a browser page
(tlac.human, docs/human-teacher.md).

    tlac teach doorkey --teachers human,optimal --advice-budget 1000 --steps 300000 --out runs/me
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tlac.argtypes import non_negative_int, positive_int
from tlac.errors import ConfigError, require_extra

DEFAULT_BUDGET = 1000.0
"""The person's questions, where ``--advice-budget`` is not given (every cost 1)."""


def with_teach_defaults(overrides: dict[str, Any]) -> dict[str, Any]:
    """``overrides`` with what ``tlac teach`` sets where they leave it out: a budget of
    :data:`DEFAULT_BUDGET` questions, and the rule ``always``. A person is asked in every state
    until the budget is spent (the page's questions come at once, as docs/human-teacher.md
    describes), not at the price of the learned rule that a budget gets elsewhere. A setting
    given directly or inside ``advice`` wins.

    >>> with_teach_defaults({})
    {'advice_budget': 1000.0, 'ask': 'always'}
    >>> with_teach_defaults({"advice": {"advice_budget": 50, "ask": "learned"}})
    {'advice': {'advice_budget': 50, 'ask': 'learned'}}
    """
    out = dict(overrides)
    advice = out.get("advice")
    for name, value in (("advice_budget", DEFAULT_BUDGET), ("ask", "always")):
        if name not in out and not (isinstance(advice, dict) and name in advice):
            out[name] = value
    return out


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not value > 0 or value != value or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def _cmd_teach(args: argparse.Namespace) -> int:
    from tlac.cli import (
        _check_teacher_names,
        _parse_overrides,
        _print_result,
        _teacher_numbers,
        with_flags,
    )
    from tlac.run import RunSpec, resolve_run, train_run

    require_extra("human", "tlac teach (a person as a teacher)", "starlette", "uvicorn")
    teachers = ["human"]
    if args.teachers is not None:
        named = [t.strip() for t in args.teachers.split(",") if t.strip()]
        if not named:
            raise ConfigError(
                f"--teachers {args.teachers!r} names no teacher; expected comma-separated names"
            )
        teachers = named if "human" in named else ["human", *named]
    if teachers.count("human") > 1:
        raise ConfigError("--teachers names human twice; there is one person at the page")
    if args.advice_budget is not None and not args.advice_budget > 0:
        raise ConfigError(f"--advice-budget must be a positive number, got {args.advice_budget}")
    overrides: dict[str, Any] = _parse_overrides(args.set)
    if args.advice_budget is not None:
        overrides["advice_budget"] = args.advice_budget
    overrides = with_teach_defaults(overrides)
    if args.teacher_cost:
        costs = {"teacher_cost": _teacher_numbers("--teacher-cost", args.teacher_cost)}
        overrides = with_flags(overrides, costs)
    eval_every = args.eval_every or max(args.steps // 20, 1000)
    spec = RunSpec(
        env=args.env,
        algo="tlac",
        teachers=teachers,
        seed=args.seed,
        steps=args.steps,
        overrides=overrides,
        eval_every=eval_every,
        eval_episodes=args.eval_episodes,
    )
    run = resolve_run(spec)
    if run.n_envs < 1:  # (resolve_run checks it; here for the type checker)
        raise ConfigError("n_envs must be at least 1")
    _check_teacher_names(spec.overrides, run.teacher_kinds)
    import gymnasium as gym

    probe = run.domain.make_env()
    if not isinstance(probe.action_space, gym.spaces.Discrete):
        raise ConfigError(
            f"tlac teach: {args.env} has {probe.action_space} actions; a person answers with "
            "buttons, one per action: Discrete actions only"
        )
    from tlac.human.session import TeachSession, action_names, drawn_run

    run = drawn_run(run)  # a Gymnasium id's environments draw the page's picture

    names = action_names(probe)
    probe.close()
    out = (
        Path(args.out)
        if args.out is not None
        else Path("runs") / f"{run.domain.name}__teach__seed{spec.seed}"
    )
    if not str(out).strip():
        raise ConfigError("--out '' names no folder; expected the run folder's path")
    budget = run.settings.advice.advice_budget  # as resolved: None is no limit
    budget_text = "no limit on questions" if budget is None else f"{budget:g} questions at most"
    with TeachSession(names, port=args.port, timeout=args.timeout) as session:
        url = session.server.url
        print(
            f"tlac teach: tlac on {args.env}, teachers [{', '.join(run.teacher_kinds)}], "
            f"{spec.steps} steps, {budget_text} -> {out}"
        )
        print(f"tlac teach: open {url}", flush=True)
        if args.open:
            import webbrowser

            webbrowser.open(url)
        try:
            result = train_run(
                run,
                out,
                progress_bar=not args.no_progress,
                on_eval=session.on_eval,
                replace=args.force,
                checkpoint_every=args.checkpoint_every,
                fresh=args.force,
                on_model=session.on_model,
            )
        except KeyboardInterrupt:
            print(
                f"tlac teach: stopped; the same command continues {out} from its last checkpoint",
                file=sys.stderr,
            )
            raise
        stats = session.desk.stats
    print(
        f"the person: {stats['answered']} answers of {stats['asked']} questions "
        f"({stats['timed_out']} timed out); advice.csv in {out}"
    )
    _print_result(result, spec.eval_episodes, out)
    return 0


def register(subparsers: Any) -> None:
    """Add ``teach`` to the main CLI's sub-parsers."""
    teach = subparsers.add_parser(
        "teach",
        help="train with a person as a teacher through a browser page (pip install 'tlac[human]')",
        description="Trains TL-AC with a local web page (127.0.0.1, a random token in its URL) "
        "where a person answers the student's questions: the state as the environment draws "
        "it, the actions as buttons with keyboard shortcuts, the student's guess, the questions "
        "left, a plot of the student alone's return and the teachers' shares, and a take-over "
        "that plays a whole episode. Questions not answered within --timeout seconds count as "
        "the person absent; every answer goes to RUN/advice.csv (replay it with --teachers "
        "replay:RUN). docs/human-teacher.md.",
    )
    teach.add_argument("env", metavar="ENV", help="domain or Gymnasium id with Discrete actions")
    teach.add_argument(
        "--teachers",
        default=None,
        help="comma-separated teachers beside the person, human (added first when not named), "
        "e.g. human,optimal or replay:RUN",
    )
    teach.add_argument(
        "--advice-budget",
        type=float,
        default=None,
        metavar="N",
        help=f"questions at most, in cost units (default {DEFAULT_BUDGET:g})",
    )
    teach.add_argument(
        "--teacher-cost", action="append", default=[], metavar="NAME=C", help="a teacher's cost"
    )
    teach.add_argument(
        "--steps", type=positive_int, default=50_000, help="environment steps (default 50000)"
    )
    teach.add_argument(
        "--port", type=non_negative_int, default=0, help="port on 127.0.0.1 (default: a free one)"
    )
    teach.add_argument(
        "--timeout",
        type=_positive_float,
        default=10.0,
        metavar="S",
        help="seconds a question waits for the person before it counts as absent (default 10)",
    )
    teach.add_argument("--out", default=None, help="run folder (default runs/ENV__teach__seedSEED)")
    teach.add_argument("--seed", type=non_negative_int, default=0)
    teach.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a TL-AC setting"
    )
    teach.add_argument(
        "--eval-every",
        type=positive_int,
        default=None,
        help="evaluate the student alone every N steps (the page's plot; default steps/20, "
        "at least 1000)",
    )
    teach.add_argument(
        "--eval-episodes", type=non_negative_int, default=10, help="episodes per evaluation"
    )
    teach.add_argument(
        "--checkpoint-every",
        type=positive_int,
        default=10_000,
        metavar="N",
        help="save a checkpoint every N steps (default 10000): Ctrl-C, then the same command, "
        "continues from it",
    )
    teach.add_argument("--open", action="store_true", help="open the page in the web browser")
    teach.add_argument("--no-progress", action="store_true", help="no progress bar")
    teach.add_argument(
        "--force", action="store_true", help="replace the run files in a non-empty --out"
    )
    teach.set_defaults(func=_cmd_teach)
