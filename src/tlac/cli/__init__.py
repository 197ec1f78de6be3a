"""The ``tlac`` command.

    tlac train                      # TL-AC on DoorKey with optimal + 2 random teachers
    tlac train --env doorkey --teachers optimal,random,random --steps 50000 --seed 0 --out runs/demo
    tlac train --env CartPole-v1 --teachers my_teachers.py:pd,agents/ppo.zip --trust-pickle
    tlac eval runs/demo --episodes 100 [--with-teachers] [--json]
    tlac envs                       # domains, their teachers and regions
    tlac teacher train|eval ...     # SAC teachers; measure any teacher
    tlac teach doorkey --advice-budget 1000   # a person as a teacher through a browser page
    tlac experiment run CONFIG --out DIR [--workers N] [--backend ray]
    tlac report DIR
    tlac results pack DIR           # DIR/runs/ -> DIR/runs.tar.xz (what the reports read)

Bad input exits with status 2 and one line on stderr naming what was wrong.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

import yaml

from tlac.argtypes import DEPLOY_MODES, non_negative_int, positive_int
from tlac.errors import ConfigError, TlacError


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as ONE line (and exit status 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parse_overrides(pairs: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs:
        if "=" not in pair:
            raise ConfigError(f"--set expects KEY=VALUE, got {pair!r}")
        key, value = pair.split("=", 1)
        try:
            out[key.strip()] = _numbers_from_text(yaml.safe_load(value))
        except yaml.YAMLError:
            raise ConfigError(f"--set {key.strip()}: {value!r} is not a YAML value") from None
    return out


def _numbers_from_text(value: Any) -> Any:
    """YAML 1.1 reads ``1e-3`` as text; a user typing it means the number."""
    if isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            return value
        return number if any(c.isdigit() for c in value) else value
    if isinstance(value, list):
        return [_numbers_from_text(v) for v in value]
    if isinstance(value, dict):
        return {k: _numbers_from_text(v) for k, v in value.items()}
    return value


def _teacher_numbers(flag: str, pairs: list[str]) -> dict[str, float]:
    """``--teacher-cost NAME=C`` / ``--availability NAME=P`` pairs as a mapping of teacher
    names to numbers (their ranges are the setting's own checks).

    >>> _teacher_numbers("--teacher-cost", ["optimal=2", "random=0.5"])
    {'optimal': 2.0, 'random': 0.5}
    """
    out: dict[str, Any] = {}
    for pair in pairs:
        name, _, value = pair.partition("=")
        if flag == "--availability" and value.startswith("linear:"):
            out[name.strip()] = _linear_availability(name, value, pair)
            continue
        try:
            number = float(value)
        except ValueError:
            number = None
        if not name.strip() or number is None:
            expected = "NAME=NUMBER"
            if flag == "--availability":
                expected += " or NAME=linear:START:END"
            raise ConfigError(f"{flag} expects {expected}, got {pair!r}")
        out[name.strip()] = number
    return out


def _linear_availability(name: str, value: str, pair: str) -> dict[str, list[float]]:
    """``--availability NAME=linear:START:END``: ``{linear: [START, END]}`` (over the run's
    progress, as every tlac schedule; its range is the setting's own check).

    >>> _linear_availability("pd", "linear:1.0:0.2", "pd=linear:1.0:0.2")
    {'linear': [1.0, 0.2]}
    """
    parts = value.split(":")[1:]
    try:
        ends = [float(v) for v in parts]
    except ValueError:
        ends = []
    if not name.strip() or len(ends) != 2:
        raise ConfigError(
            f"--availability expects NAME=NUMBER or NAME=linear:START:END, got {pair!r}"
        )
    return {"linear": ends}


def _advice_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The TL-AC settings of ``--advice-budget``, ``--teacher-cost`` and ``--availability``."""
    out: dict[str, Any] = {}
    if args.advice_budget is not None:
        out["advice_budget"] = args.advice_budget
    for flag, key, pairs in (
        ("--teacher-cost", "teacher_cost", args.teacher_cost),
        ("--availability", "availability", args.availability),
    ):
        if pairs:
            out[key] = _teacher_numbers(flag, pairs)
    if out and args.algo != "tlac":
        raise ConfigError(
            f"--advice-budget, --teacher-cost and --availability are TL-AC's; not {args.algo}'s"
        )
    return out


def with_flags(overrides: dict[str, Any], flags: dict[str, Any]) -> dict[str, Any]:
    """``--set``'s settings with the advice flags' on top: a per-teacher mapping given both
    ways (by its name, or inside ``advice``) is merged teacher by teacher (the flag's value
    wins), not replaced whole; the merged mapping goes by its name, which wins over
    ``advice``'s (tlac.two_level.config.fold_advice_settings).

    >>> with_flags({"availability": {"pd": 0.5}, "n_steps": 8}, {"availability": {"coin": 0.2}})
    {'availability': {'pd': 0.5, 'coin': 0.2}, 'n_steps': 8}
    >>> with_flags({"advice": {"availability": {"pd": 0.5}}}, {"availability": {"coin": 0.2}})
    {'advice': {'availability': {'pd': 0.5}}, 'availability': {'pd': 0.5, 'coin': 0.2}}
    """
    out = dict(overrides)
    nested = out.get("advice") if isinstance(out.get("advice"), dict) else {}
    for key, value in flags.items():
        given = [g for g in (nested.get(key), out.get(key)) if isinstance(g, dict)]
        out[key] = {k: v for g in (*given, value) for k, v in g.items()} if given else value
    return out


def _check_teacher_names(overrides: dict[str, Any], names: list[str]) -> None:
    """A --teacher-cost / --availability name that is no teacher of the run: one ConfigError
    before anything is built (tlac.algorithms.advice.per_teacher)."""
    from tlac.algorithms.advice import per_teacher_values
    from tlac.teachers.base import unique_names

    for key in ("teacher_cost", "availability"):
        if isinstance(overrides.get(key), dict):
            per_teacher_values(overrides[key], unique_names(names), key, 1.0)


def _cmd_train(args: argparse.Namespace) -> int:
    from tlac.algorithms import NO_ADVICE
    from tlac.run import RunSpec, load_run_config, resolve_run, resume_run, train_run

    if args.resume is not None:
        config = load_run_config(args.resume)
        kinds = config.get("teacher_kinds")
        if isinstance(kinds, list) and "human" in kinds:  # (a bad value: resume_run names it)
            raise ConfigError(
                f"{args.resume!r} has a person as a teacher: continue it with the tlac teach "
                "command that started it (the same --out)"
            )
        print(f"tlac train: resuming {args.resume} ({config['algo']} on {config['env']})")
        result = resume_run(
            args.resume,
            progress_bar=not args.no_progress,
            checkpoint_every=args.checkpoint_every,
            trust_pickle=args.trust_pickle,
        )
        _print_result(result, int(config.get("eval_episodes", 0)), Path(args.resume))
        return 0

    teachers = (
        None
        if args.teachers is None
        else [t.strip() for t in args.teachers.split(",") if t.strip()]
    )
    if teachers == [] and args.teachers is not None:
        raise ConfigError(
            f"--teachers {args.teachers!r} names no teacher; expected comma-separated names"
        )
    if args.algo in NO_ADVICE and teachers:
        raise ConfigError(f"--algo {args.algo} learns without advice; drop --teachers")
    if teachers and "human" in teachers:
        raise ConfigError(
            "the teacher human is a person at a browser page: train with tlac teach ENV "
            "--teachers ... (docs/human-teacher.md)"
        )
    spec = RunSpec(
        env=args.env,
        algo=args.algo,
        teachers=teachers,
        seed=args.seed,
        steps=args.steps,
        selector=args.selector,
        preset=args.preset,
        overrides=with_flags(_parse_overrides(args.set), _advice_overrides(args)),
        eval_every=args.eval_every,
        eval_episodes=args.eval_episodes,
        log_interval=args.log_interval,
        tensorboard=args.tensorboard,
        keep_best=args.eval_every is not None and not args.keep_last,
        deploy=args.deploy,
    )
    run = resolve_run(spec, args.trust_pickle)
    if args.out is not None and not args.out.strip():
        raise ConfigError("--out '' names no folder; expected the run folder's path")
    # domain.name, not spec.env: a domain given as path/to/file.py:ATTR must not become a path
    out = (
        Path(args.out)
        if args.out is not None
        else Path("runs") / f"{run.domain.name}__{spec.algo}__seed{spec.seed}"
    )
    names = run.teacher_kinds
    _check_teacher_names(spec.overrides, names)
    print(
        f"tlac train: {spec.algo} on {spec.env}, teachers [{', '.join(names) or 'none'}], "
        f"{spec.steps} steps, seed {spec.seed} -> {out}"
    )

    def report_eval(timestep: int, student: float, train_return: float | None) -> None:
        from tqdm.auto import tqdm

        train = "n/a" if train_return is None else f"{train_return:.3f}"
        mode = "the better of greedy and sampled" if spec.deploy == "choose" else spec.deploy
        tqdm.write(
            f"step {timestep}: student alone {student:.3f} ({mode}, {spec.eval_episodes} "
            f"episodes) | training return {train} (teachers included)"
        )

    result = train_run(
        run,
        out,
        progress_bar=not args.no_progress,
        on_eval=report_eval,
        replace=args.force,
        checkpoint_every=args.checkpoint_every,
        fresh=args.force,
        trust_pickle=args.trust_pickle,
    )
    _print_result(result, spec.eval_episodes, out)
    return 0


def _print_result(result: dict[str, Any], eval_episodes: int, out: Path) -> None:
    print(
        f"trained {result['steps']} steps in {result['wall_time_s']:.0f} s "
        f"({result['steps_per_s']:.0f} steps/s), {result['episodes']} episodes"
    )
    if result["final_train_return_mean"] is not None:
        train_return = result["final_train_return_mean"]
        print(f"training return, last episodes (teachers included): {train_return:.3f}")
    if result["final_eval_mean"] is not None:
        kept = result.get("student_kept_from_step")
        source = "" if kept is None else f"; the student kept from step {kept}"
        if "deployed_from_step" in result:  # keep_best
            source = (
                f"; the model of the best evaluation, step {result['deployed_from_step']} "
                f"({result['deployed_selection_mean']:.3f} there), on fresh episodes{source}"
            )
        elif "deployed_selection_mean" in result:  # deploy choose, the last weights
            source = (
                f"; the mode of the last evaluation ({result['deployed_selection_mean']:.3f} "
                f"there), on fresh episodes{source}"
            )
        mode = result.get("deploy_mode", "greedy")
        print(
            f"student alone (no teachers, {mode}{source}), {eval_episodes} episodes: "
            f"{result['final_eval_mean']:.3f} +- {result['final_eval_std']:.3f}"
        )
        if result.get("deployed_from_step", result["steps"]) != result["steps"]:
            print(
                f"the last weights (model-last), student alone at the last evaluation: "
                f"{result['last_eval_mean']:.3f} +- {result['last_eval_std']:.3f}"
            )
    print(f"run folder: {out} (episodes.csv, teacher_usage.csv, eval.csv, config.yaml, model)")


def _cmd_eval(args: argparse.Namespace) -> int:
    import numpy as np

    from tlac.domains import get_domain, make_teachers
    from tlac.evaluation import evaluate_policy, evaluate_student
    from tlac.experiments.config import domain_file
    from tlac.run import load_run_config, load_run_model
    from tlac.teachers.files import check_teacher_files
    from tlac.teachers.sb3 import check_trust_pickle

    config = load_run_config(args.run_dir)
    run = Path(args.run_dir)
    if not any((run / f"model{ext}").exists() for ext in (".pt", ".zip")):
        raise ConfigError(
            f"{str(run)!r} has no trained model (model.pt / model.zip): the run did not finish"
        )
    if domain_file(config["env"]) is not None and not args.trust_code:
        raise ConfigError(
            f"{str(run)!r} was trained on the domain file {config['env']!r}: importing it runs "
            "its code, so tlac eval imports it only when told to; pass --trust-code if you "
            "trust the file (one you wrote)"
        )
    kinds = (config.get("teacher_kinds") or []) if args.with_teachers else []
    if not isinstance(kinds, list) or not all(isinstance(k, str) for k in kinds):
        raise ConfigError(f"{str(run / 'config.yaml')!r}: teacher_kinds must be a list of names")
    _check_teacher_code(kinds, args.trust_code)
    check_teacher_files(kinds, args.trust_pickle)
    if not (run / "model.pt").exists():  # an SB3 baseline's model.zip: a pickle
        check_trust_pickle(run / "model.zip", args.trust_pickle, "--trust-pickle")
    domain = get_domain(config["env"])
    model = load_run_model(run, config["algo"], trust_pickle=args.trust_pickle)
    trained_on = getattr(model, "env_name", None)  # recorded by TL-AC's model files
    if isinstance(trained_on, str) and trained_on != domain.name:
        from tlac.two_level.inputs import other_env_warning

        print(f"tlac: warning: {other_env_warning(trained_on, domain.name)}", file=sys.stderr)
    seed = args.seed
    mode = "sampled" if args.stochastic else "greedy" if args.greedy else _deployed_mode(run)
    returns = evaluate_student(model, domain, args.episodes, seed, deterministic=mode == "greedy")
    result: dict[str, Any] = {
        "run": str(run),
        "env": config["env"],
        "algo": config["algo"],
        "mode": mode,
        "episodes": len(returns),
        "student_mean": float(np.mean(returns)),
        "student_std": float(np.std(returns)),
    }
    if args.with_teachers:
        if not kinds:
            raise ConfigError(f"{str(run)!r} was trained without teachers; drop --with-teachers")
        if not hasattr(model, "predict_with_teachers"):
            raise ConfigError(
                f"algorithm {config['algo']!r} cannot act with its teachers outside training"
            )
        probe = domain.make_env()
        model.teachers = make_teachers(domain, kinds, probe, config["seed"], args.trust_pickle)
        with_teachers = evaluate_policy(
            lambda o: model.predict_with_teachers(o), domain, args.episodes, seed
        )
        result.update(
            with_teachers_mean=float(np.mean(with_teachers)),
            with_teachers_std=float(np.std(with_teachers)),
        )
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"student alone ({mode}, {len(returns)} episodes): "
            f"{result['student_mean']:.3f} +- {result['student_std']:.3f}"
        )
        if args.with_teachers:
            print(
                f"with its teachers ({len(returns)} episodes): "
                f"{result['with_teachers_mean']:.3f} +- {result['with_teachers_std']:.3f}"
            )
    return 0


def _deployed_mode(run: Path) -> str:
    """How the run deploys its student (``result.json``'s ``deploy_mode``; greedy for a run
    made before runs recorded it)."""
    try:
        mode = json.loads((run / "result.json").read_text()).get("deploy_mode", "greedy")
    except (OSError, ValueError, AttributeError):
        return "greedy"
    return mode if mode in ("greedy", "sampled") else "greedy"


def _check_teacher_code(kinds: list[str], trust_code: bool) -> None:
    """ConfigError for a teacher named by a Python file, which ``tlac eval --with-teachers``
    imports (running its code) only with ``--trust-code``."""
    from tlac.teachers.files import teacher_file

    for kind in kinds:
        found = teacher_file(kind)
        if found is not None and found.kind == "python" and not trust_code:
            raise ConfigError(
                f"teacher {kind!r} is a Python file: importing it runs its code, so tlac eval "
                "imports it only when told to; pass --trust-code if you trust the file"
            )


def _cmd_envs(args: argparse.Namespace) -> int:
    from tlac.domains import domain_names, get_domain

    for name in domain_names():
        try:
            d = get_domain(name)
        except TlacError as exc:
            print(f"{name:14s} unavailable: {exc}")
            continue
        print(f"{name:14s} {d.description}")
        print(
            f"{'':14s} teachers: {', '.join(d.teacher_names)}; regions: {', '.join(d.region_names)}"
        )
    from tlac.gym_ids import GYM_IDS

    print(f"\nThe same domains as Gymnasium ids (gym.make): {', '.join(GYM_IDS)}")
    print(
        "Any registered Gymnasium id (CartPole-v1, ...) works from Python: "
        "TLAC('CartPole-v1', teachers=[...]);\non the command line with teachers from files: "
        "tlac train --env CartPole-v1 --teachers path/to/file.py:NAME,path/to/agent.zip "
        "--trust-pickle,\nor a domain file that makes it and names its teachers: tlac train "
        "--env path/to/file.py:DOMAIN (examples/my_domain.py)."
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    from tlac import __version__
    from tlac.algorithms import algorithm_names
    from tlac.selectors import SELECTOR_NAMES

    parser = _Parser(
        prog="tlac", description="Reinforcement learning with advice from several teachers (TL-AC)."
    )
    parser.add_argument("--version", action="version", version=f"tlac {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    train = sub.add_parser("train", help="train one run and write its run folder")
    train.add_argument(
        "--env",
        default="doorkey",
        help="domain (see `tlac envs`; default doorkey), a domain file path/to/file.py:DOMAIN "
        "(examples/my_domain.py), or a registered Gymnasium id (CartPole-v1) with --teachers",
    )
    train.add_argument(
        "--algo", default="tlac", choices=algorithm_names(), help="algorithm (default tlac)"
    )
    train.add_argument(
        "--teachers",
        default=None,
        help="comma-separated teacher names of the domain (default: the domain's "
        "default set), or teachers from files: path/to/file.py:NAME (a function of one "
        "observation, an object with predict, an SB3 model), path/to/agent.zip or an rl-zoo run "
        "folder (SB3 agents: with --trust-pickle); NAME:P mixes NAME with random actions, "
        "P = P(NAME's action)",
    )
    train.add_argument(
        "--steps", type=positive_int, default=50_000, help="environment steps (default 50000)"
    )
    train.add_argument("--seed", type=non_negative_int, default=0)
    train.add_argument("--out", default=None, help="run folder (default runs/ENV__ALGO__seedSEED)")
    train.add_argument(
        "--selector",
        default="learned",
        choices=SELECTOR_NAMES,
        help="TL-AC's high level: learned (the paper), random or ucb1 (ablations)",
    )
    train.add_argument(
        "--preset", default=None, help="hyperparameter preset (default: the domain's)"
    )
    train.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a hyperparameter, e.g. --set n_epochs=10 (YAML values)",
    )
    train.add_argument(
        "--advice-budget",
        type=float,
        default=None,
        metavar="N",
        help="TL-AC: the advice budget in cost units (every cost 1: answers), paced over the "
        "run by the learned asking rule unless --set ask=... names another; once spent, no "
        "teacher is asked again (docs/advice.md)",
    )
    train.add_argument(
        "--teacher-cost",
        action="append",
        default=[],
        metavar="NAME=C",
        help="TL-AC: a teacher's cost per answer (default 1); repeat per teacher",
    )
    train.add_argument(
        "--availability",
        action="append",
        default=[],
        metavar="NAME=P",
        help="TL-AC: a teacher's chance to be present in an episode (default 1), or "
        "NAME=linear:START:END, a chance going from START to END over the run; repeat per "
        "teacher (a step schedule: --set availability='{NAME: {steps: [[0, 1], [20000, 0]]}}')",
    )
    train.add_argument(
        "--eval-every",
        type=positive_int,
        default=None,
        help="evaluate the student alone every N steps (default: at the end only)",
    )
    train.add_argument(
        "--eval-episodes",
        type=non_negative_int,
        default=20,
        help="episodes per student-alone evaluation (default 20)",
    )
    train.add_argument(
        "--keep-last",
        action="store_true",
        help="with --eval-every: deploy the last weights (model) rather than the student of "
        "the best evaluation (the default: model, scored again on fresh episodes; the last "
        "weights in model-last)",
    )
    train.add_argument(
        "--deploy",
        choices=DEPLOY_MODES,
        default="greedy",
        help="how the student alone is scored and deployed: greedy (default), sampled "
        "(predict's default, as SB3's), or choose: every evaluation scores both and the run "
        "deploys the mode of its best evaluation (of its last with --keep-last or without "
        "--eval-every), scored again on fresh episodes; result.json's deploy_mode names it and "
        "tlac eval uses it",
    )
    train.add_argument(
        "--log-interval", type=positive_int, default=2000, help="steps per logging window"
    )
    train.add_argument(
        "--tensorboard", action="store_true", help="also write TensorBoard logs to RUN/tb"
    )
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.add_argument(
        "--trust-pickle",
        action="store_true",
        help="open the SB3 agents given as --teachers (.zip, vecnormalize.pkl): their pickles "
        "can run code when loaded, so only files you trust",
    )
    train.add_argument(
        "--resume",
        metavar="RUN",
        default=None,
        help="continue the unfinished run RUN (TL-AC, DQN-TLQL, AC-Teach) from its last checkpoint "
        "(other flags except --no-progress and --checkpoint-every are taken from RUN/config.yaml)",
    )
    train.add_argument(
        "--checkpoint-every",
        type=positive_int,
        default=50_000,
        metavar="N",
        help="save a checkpoint every N steps (TL-AC, DQN-TLQL, AC-Teach: with the full "
        "training state, for an exact resume; default 50000)",
    )
    train.add_argument(
        "--force",
        action="store_true",
        help="replace the run files in a non-empty --out (a finished run included) and start "
        "afresh (without it, an unfinished run of the same settings continues)",
    )
    train.set_defaults(func=_cmd_train)

    ev = sub.add_parser(
        "eval", help="evaluate a run's student alone (and optionally with its teachers)"
    )
    ev.add_argument("run_dir", help="a run folder written by `tlac train`")
    ev.add_argument("--episodes", type=positive_int, default=100)
    ev.add_argument(
        "--seed", type=non_negative_int, default=123_456, help="seed of the first episode"
    )
    ev.add_argument(
        "--with-teachers",
        action="store_true",
        help="also evaluate the high level with its teachers",
    )
    mode = ev.add_mutually_exclusive_group()
    mode.add_argument(
        "--stochastic",
        action="store_true",
        help="sample the student's actions (default: as the run deploys them, result.json's "
        "deploy_mode; greedy for a run without one)",
    )
    mode.add_argument("--greedy", action="store_true", help="the student's greedy actions")
    ev.add_argument("--json", action="store_true", help="print one JSON object")
    ev.add_argument(
        "--trust-pickle",
        action="store_true",
        help="open an SB3 baseline's model.zip (A2C, PPO), or with --with-teachers the SB3 "
        "agents the run names as teachers: their pickles can run code when loaded, so only "
        "for a run you trust",
    )
    ev.add_argument(
        "--trust-code",
        action="store_true",
        help="import the run's domain file (path/to/file.py:DOMAIN), or with --with-teachers "
        "its teachers' Python files: importing them runs their code, so only files you trust",
    )
    ev.set_defaults(func=_cmd_eval)

    envs = sub.add_parser("envs", help="list the domains, their teachers and regions")
    envs.set_defaults(func=_cmd_envs)

    from tlac.cli import teacher as teacher_cli

    teacher_cli.register(sub)
    from tlac.cli import experiment as experiment_cli

    experiment_cli.register(sub)
    from tlac.cli import results as results_cli

    results_cli.register(sub)
    from tlac.cli import teach as teach_cli

    teach_cli.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except TlacError as exc:
        print(f"tlac: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("tlac: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `tlac envs | head`: the reader left; say nothing more
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - replaces the closed stream
        return 0


if __name__ == "__main__":
    sys.exit(main())
