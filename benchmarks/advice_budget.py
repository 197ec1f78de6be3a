"""Advice that costs (issue 66): the student ALONE, and the answers it used, per asking rule,
budget and availability, beside PPO alone.

Per case (DoorKey with 1 optimal + 2 random teachers or the L + R pair, both on the domain's
preset; MountainCar-v0 and CartPole-v1 with their scripted teacher and a random one, on
tlac's default preset, benchmarks/user_envs.py) and per TL-AC run of an asking rule
(``--rules``: learned, early, importance, uncertainty, mistake; docs/advice.md), an advice budget
(``--budgets``, answers: every teacher costs 1; ``inf``: no limit) and an availability
(``--availability``: every teacher present in an episode with that chance), every
``--eval-every`` steps the student ALONE is scored greedily on the user suite's fresh
evaluation episodes (benchmarks/peers.py's :class:`peers.Curve`), with the answers asked so far.
PPO alone (``ppo``: SB3's defaults; DoorKey's ``ppo`` preset) is run once per case and seed.
With ``--deploy choose`` each learner is also deployed at the end greedy or sampled, whichever
scores higher on other episodes, and that score on the fresh ones is its student alone at the
end (on DoorKey a greedy student walks in loops a sampled one leaves: docs/advice.md).

Every TL-AC run here sets ``teacher_episodes 0`` (no teacher-led episodes, so no audition): a
led episode asks its teacher in every state whatever the rule (CartPole's scripted teacher
spends 1,500 answers in the audition's three episodes), so with it the rules would differ only
after the audition has spent a budget of 1e3. ``ask learned`` on a budget sets it itself.

Every run is a JSON file under ``--out``/runs, skipped when present, so a killed grid resumes
where it stopped. ``--phase report`` (also run after every grid) writes ``report.md`` (the
student alone at the end beside the training return, and the answers used, mean +- std over
seeds) and one figure per case
(``<case>.png``: the student alone against the steps, one line per rule, budget and
availability, PPO alone dotted; beside it the answers used; with several budgets, the student
alone at the end against the budget), and an overview (``--overview``, default
``<out>/advice_budget.png``: the student alone at the end against the budget, one panel per
case, learned, early and importance advising, PPO alone dotted).

    .venv/bin/python benchmarks/advice_budget.py --envs CartPole-v1 --budgets 1e3 --seeds 0
    .venv/bin/python benchmarks/advice_budget.py --phase report
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # (the cases' environments, teachers, evaluation and PPO)
import user_envs

CASES = ("DoorKey+1optimal-2random", "DoorKey+L-R", "MountainCar-v0", "CartPole-v1")
RULES = ("learned", "early", "importance", "uncertainty", "mistake")
BUDGETS = ("1e2", "1e3", "1e4", "inf")
AVAILABILITY = (1.0, 0.5)
BENCH_SETTINGS: dict[str, Any] = {"teacher_episodes": 0.0}
"""What every TL-AC run sets on top of its case's preset (the module's docstring says why)."""


def budget_value(text: str) -> float | None:
    """``--budgets``' word as the run's ``advice_budget``: None for ``inf`` (no limit).

    >>> budget_value("1e3"), budget_value("inf")
    (1000.0, None)
    """
    value = float(text)
    return None if math.isinf(value) else value


def run_name(case: str, learner: str, budget: str, availability: float, seed: int) -> str:
    """The run's file name (PPO alone: no budget, no availability).

    >>> run_name("CartPole-v1", "learned", "1e3", 0.5, 2)
    'CartPole-v1__learned__b1e3__a0.5__seed2.json'
    >>> run_name("CartPole-v1", "ppo", "1e3", 0.5, 2)
    'CartPole-v1__ppo__seed2.json'
    """
    if learner == "ppo":
        return f"{case}__ppo__seed{seed}.json"
    return f"{case}__{learner}__b{budget}__a{availability:g}__seed{seed}.json"


def teacher_specs(case: str, seed: int, env: Any, availability: float) -> list[Any]:
    """The case's teachers, each present in an episode with ``availability``."""
    from tlac.teachers import TeacherSpec

    if peers.is_doorkey(case):
        policies = peers.DOORKEY_CASES[case]
    else:
        policies = user_envs.SUITE[case](seed, env.action_space)
    return [TeacherSpec(p, availability=availability) for p in policies]


def deployment(model: Any, case: str, args: argparse.Namespace) -> dict[str, Any]:
    """With ``--deploy choose``, how the trained learner is deployed (``deployed``: greedy or
    sampled, chosen on other episodes; :func:`peers.deployed_alone`) and its score then on
    fresh episodes (``student_alone``); nothing with ``--deploy greedy`` (the curve's last
    point is the greedy student's score)."""
    if args.deploy == "greedy":
        return {}
    modes = {"greedy": peers.greedy(model), "sampled": peers.sampled(model)}
    return peers.deployed_alone(modes, case, args.episodes)


def train_tlac(
    case: str, rule: str, budget: str, availability: float, seed: int, args: argparse.Namespace
) -> dict[str, Any]:
    from tlac import TLAC
    from tlac.recording import find_episode_recorder

    settings = {**BENCH_SETTINGS, **user_envs.parse_settings(args.tlac_setting)}
    settings.update(ask=rule, advice_budget=budget_value(budget))
    env = "doorkey" if peers.is_doorkey(case) else peers.make_env(case)
    teachers = teacher_specs(case, seed, None if env == "doorkey" else env, availability)
    model = TLAC(env, teachers=teachers, seed=seed, **settings)
    curve = peers.Curve(case, args.eval_every, args.episodes)
    answers: list[list[float]] = []  # [steps, answers so far, spent so far]

    def after_update(m: Any) -> bool:
        if curve.due(m.num_timesteps):
            training = find_episode_recorder(m.env).episode_returns
            curve.record(m.num_timesteps, peers.greedy(m), training)
            answers.append([m.num_timesteps, int(m.advice.answers.sum()), m.advice.spent])
        return True

    model.learn(args.steps, callback=after_update)
    return {
        **deployment(model, case, args),
        "case": case,
        "learner": rule,
        "budget": budget,
        "availability": availability,
        "seed": seed,
        "steps": args.steps,
        "settings": settings,
        "curve": curve.points,
        "answers": answers,
        "advice": model.advice.summary(model.teacher_names),
    }


def train_ppo(case: str, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    curve = peers.Curve(case, args.eval_every, args.episodes)
    model = peers.train_ppo(case, seed, args.steps, curve, None)
    return {
        **deployment(model, case, args),
        "case": case,
        "learner": "ppo",
        "seed": seed,
        "steps": args.steps,
        "curve": curve.points,
    }


# ------------------------------------------------------------------ the report
def load_runs(out: Path) -> list[dict[str, Any]]:
    return [json.loads(p.read_text()) for p in sorted((out / "runs").glob("*.json"))]


def final_score(run: dict[str, Any]) -> float:
    """The student alone at the end: as deployed where the run chose (``--deploy choose``), else
    greedy at the run's last evaluation."""
    return float(run["student_alone"] if "deployed" in run else run["curve"][-1][1])


def final_training_return(run: dict[str, Any]) -> float | None:
    """The training episodes' return at the run's last evaluation (None: no episode yet)."""
    value = run["curve"][-1][3]
    return None if value is None else float(value)


def answers_used(run: dict[str, Any]) -> float:
    return float(sum(t["answers"] for t in run["advice"]["teachers"].values()))


def groups(runs: list[dict[str, Any]], case: str) -> dict[tuple, list[dict[str, Any]]]:
    """The case's runs by (learner, budget, availability); PPO's by ("ppo", "", 1.0)."""
    out: dict[tuple, list[dict[str, Any]]] = {}
    for run in runs:
        if run["case"] != case:
            continue
        key = (
            (run["learner"], "", 1.0)
            if run["learner"] == "ppo"
            else (run["learner"], run["budget"], float(run["availability"]))
        )
        out.setdefault(key, []).append(run)
    return out


def _mean_std(values: list[float], decimals: int = 1) -> str:
    if len(values) == 1:
        return f"{values[0]:.{decimals}f}"
    return f"{np.mean(values):.{decimals}f} +- {np.std(values):.{decimals}f}"


def case_table(case: str, by_key: dict[tuple, list[dict[str, Any]]]) -> list[str]:
    def order(key: tuple) -> tuple:
        learner, budget, availability = key
        learners = (*RULES, "ppo")
        rank = learners.index(learner) if learner in learners else 99
        return (float(budget) if budget else -1.0, -availability, rank)

    decimals = 3 if peers.is_doorkey(case) else 1  # DoorKey's returns lie in [0, 1]
    lines = []
    for key in sorted(by_key, key=order):
        learner, budget, availability = key
        rs = by_key[key]
        steps = rs[0]["curve"][-1][0]
        score = _mean_std([final_score(r) for r in rs], decimals) + peers.deployed_note(rs)
        returns = [v for v in map(final_training_return, rs) if v is not None]
        training = _mean_std(returns, decimals) if returns else "-"
        if learner == "ppo":
            lines.append(
                f"| {case} | PPO alone | - | - | {len(rs)} | {steps} | {score} | {training} | 0 |"
            )
            continue
        used = _mean_std([answers_used(r) for r in rs], 0)
        lines.append(
            f"| {case} | {learner} | {budget} | {availability:g} | {len(rs)} | {steps} "
            f"| {score} | {training} | {used} |"
        )
    return lines


def _mean_curve(rows: list[list[list[float]]], column: int) -> tuple[list[float], list[float]]:
    """Steps and the seeds' mean of ``column`` at each evaluation they all reached."""
    n = min(len(r) for r in rows)
    steps = [rows[0][i][0] for i in range(n)]
    return steps, [float(np.mean([r[i][column] for r in rows])) for i in range(n)]


def plot_case(out: Path, case: str, by_key: dict[tuple, list[dict[str, Any]]]) -> None:
    """``<case>.png``: the student alone (greedy) against the environment steps, per rule,
    budget and availability (seed means; PPO alone dotted), beside the answers used so far;
    and, where more than one budget was run, the student alone at the end against the budget."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 3 if len({k[1] for k in by_key if k[0] != "ppo"}) > 1 else 2
    fig, axes = plt.subplots(1, panels, figsize=(5 * panels, 4))
    alone, used_ax = axes[0], axes[1]
    styles = {1.0: "-", 0.5: "--"}
    colors = {rule: f"C{i}" for i, rule in enumerate(RULES)}
    markers = dict(zip(BUDGETS, "v.s*", strict=True))  # the budget: its marker
    for key in sorted(k for k in by_key if k[0] != "ppo"):
        rule, budget, availability = key
        rs = by_key[key]
        label = f"{rule}, budget {budget}, availability {availability:g}"
        style = styles.get(availability, ":")
        steps, scores = _mean_curve([r["curve"] for r in rs], 1)
        marker = markers.get(budget, "x")
        alone.plot(steps, scores, style, color=colors.get(rule), label=label, marker=marker)
        steps, answers = _mean_curve([r["answers"] for r in rs], 1)
        used_ax.plot(steps, answers, style, color=colors.get(rule), label=label, marker=marker)
    ppo = by_key.get(("ppo", "", 1.0))
    if ppo:
        steps, scores = _mean_curve([r["curve"] for r in ppo], 1)
        alone.plot(steps, scores, ":", color="grey", label="PPO alone", marker=".")
    alone.set_xlabel("environment steps")
    alone.set_ylabel("return of the student alone (greedy)")
    alone.set_title(f"{case}: the student alone")
    alone.legend(fontsize=6)
    used_ax.set_xlabel("environment steps")
    used_ax.set_ylabel("answers used so far")
    used_ax.set_title("answers used")
    if panels == 3:
        ax = axes[2]
        plot_against_budget(ax, by_key, RULES)
        ax.set_ylabel("student alone at the end")
        ax.set_title("against the budget")
    fig.tight_layout()
    fig.savefig(out / f"{case}.png", dpi=100)
    plt.close(fig)


OVERVIEW_RULES = ("learned", "early", "importance")
"""The rules the overview figure draws: the issue's acceptance compares these."""


def budget_positions(budgets: list[str]) -> dict[str, float]:
    """Where each budget lies on the overview's log axis: its number of answers, and no limit
    ten times past the largest finite one.

    >>> budget_positions(["1e3", "inf", "1e2"])
    {'1e2': 100.0, '1e3': 1000.0, 'inf': 10000.0}
    """
    finite = sorted(float(b) for b in budgets if math.isfinite(float(b)))
    beyond = 10 * (finite[-1] if finite else 1e3)
    return {
        b: (float(b) if math.isfinite(float(b)) else beyond)
        for b in sorted(budgets, key=lambda b: float(b))
    }


def plot_against_budget(ax: Any, by_key: dict[tuple, list[dict[str, Any]]], rules: tuple) -> None:
    """On ``ax``: the student alone at the end (seed mean) against the budget, per rule of
    ``rules`` (filled markers: availability 1; hollow, dashed: any other), PPO alone dotted."""
    where = budget_positions(sorted({k[1] for k in by_key if k[0] != "ppo"}))
    for rule in rules:
        for availability in sorted({k[2] for k in by_key if k[0] == rule}, reverse=True):
            keys = [(rule, b, availability) for b in where if (rule, b, availability) in by_key]
            full = availability == 1.0
            ax.plot(
                [where[k[1]] for k in keys],
                [seed_mean(by_key[k]) for k in keys],
                "-" if full else "--",
                marker="o",
                color=f"C{RULES.index(rule)}",
                markerfacecolor=None if full else "none",
                label=rule + ("" if full else f", availability {availability:g}"),
            )
    ppo = by_key.get(("ppo", "", 1.0))
    if ppo:
        ax.axhline(seed_mean(ppo), color="grey", ls=":", label="PPO alone")
    ax.set_xscale("log")
    ax.set_xticks(list(where.values()))
    ax.set_xticklabels(["no limit" if b == "inf" else b for b in where])
    ax.set_xlabel("advice budget (answers)")


def plot_overview(path: Path, by_case: dict[str, dict[tuple, list[dict[str, Any]]]]) -> None:
    """One panel per case (:func:`plot_against_budget` with :data:`OVERVIEW_RULES`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = [c for c in CASES if any(k[0] != "ppo" for k in by_case.get(c, {}))]
    if not cases:
        return
    fig, axes = plt.subplots(1, len(cases), figsize=(4 * len(cases), 3.6), squeeze=False)
    for ax, case in zip(axes[0], cases, strict=True):
        plot_against_budget(ax, by_case[case], OVERVIEW_RULES)
        ax.set_title(case, fontsize=9)
    axes[0][0].set_ylabel("student alone at the end (seed mean)")
    axes[0][0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def seed_mean(runs: list[dict[str, Any]] | None) -> float | None:
    """The seeds' mean of the student alone at the end (None: no run)."""
    return float(np.mean([final_score(r) for r in runs])) if runs else None


def learned_holds(learned: float, others: list[float | None]) -> bool:
    """Issue 66's first point: the learned asking's student at or above every other learner's
    (the rules run and PPO alone; None: not run, so not compared).

    >>> learned_holds(-113.0, [-133.0, -113.1, -200.0])
    True
    >>> learned_holds(-113.7, [-133.0, -113.1, None])
    False
    """
    return all(learned >= other for other in others if other is not None)


def margin_share(score: float, reference: float, random_return: float) -> float:
    """``score``'s margin over the random policy as a share of ``reference``'s: issue 66's
    "95% of the always-available one's" read on the margin over random, so that it means the
    same on MountainCar's negative returns as on CartPole's positive ones.

    >>> margin_share(-120.0, -110.0, -200.0)
    0.8888888888888888
    >>> margin_share(500.0, 500.0, 22.0)
    1.0
    """
    return (score - random_return) / (reference - random_return)


def random_return(out: Path, case: str) -> float:
    """The uniformly random policy's return on the case's evaluation episodes, kept in
    ``out``/reference/<case>.json once measured."""
    path = out / "reference" / f"{case}.json"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        measured = peers.reference_returns(case, user_envs.EVAL_EPISODES)
        path.write_text(json.dumps(measured, indent=1))
    return float(json.loads(path.read_text())["random_policy"])


def verdict_table(
    case: str, by_key: dict[tuple, list[dict[str, Any]]], random_policy: float
) -> list[str]:
    """Per budget and availability the learned asking's student (seed mean) beside early's,
    importance's and PPO alone's, and at availability 0.5 its margin over random as a share of
    the always-available one's: the issue's acceptance, each mean over the seeds that every
    group compared has (5 asked), so that a grid still running compares like with like."""
    places = 3 if peers.is_doorkey(case) else 1  # DoorKey's returns lie in [0, 1]
    lines = []
    for key in sorted(k for k in by_key if k[0] == "learned"):
        _, budget, availability = key
        groups_compared = [
            by_key[key],
            *(by_key.get((rule, budget, availability)) for rule in ("early", "importance")),
            by_key.get(("ppo", "", 1.0)),
            by_key.get(("learned", budget, 1.0)) if availability != 1.0 else None,
        ]
        seeds = set.intersection(*({r["seed"] for r in g} for g in groups_compared if g))
        if not seeds:
            continue
        learned, early, importance, ppo, always = (
            seed_mean([r for r in g if r["seed"] in seeds]) if g else None for g in groups_compared
        )
        holds = learned_holds(learned, [early, importance, ppo])
        share = "-"
        if always is not None and always != random_policy:
            ratio = margin_share(learned, always, random_policy)
            share = f"{ratio:.2f} ({'yes' if ratio >= 0.95 else 'NO'})"
        shown = [f"{v:.{places}f}" if v is not None else "-" for v in (early, importance, ppo)]
        lines.append(
            f"| {case} | {budget} | {availability:g} | {len(seeds)} | {learned:.{places}f} "
            f"| {' | '.join(shown)} | {'yes' if holds else 'NO'} | {share} |"
        )
    return lines


def report(out: Path, overview: Path | None = None) -> str:
    """report.md's tables; the per-case figures in ``out``, and the overview figure
    (:func:`plot_overview`) at ``overview`` (None: ``out``/advice_budget.png)."""
    runs = load_runs(out)
    lines = [
        "| case | rule | budget | availability | seeds | steps | student alone at the end "
        "| training return at the end | answers used |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    verdicts = [
        "",
        "The acceptance (seed means of the student alone at the end, over the seeds every "
        "group compared in a row has; the issue asks 5). "
        "`learned >= the others`: at or above early's, importance's and PPO alone's (those run). "
        "At availability 0.5: the learned student's margin over the random policy as a share "
        "of the always-available one's (>= 0.95 asked).",
        "",
        "| case | budget | availability | seeds | learned | early | importance | PPO alone "
        "| learned >= the others | availability 0.5 / 1 |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    by_case = {case: groups(runs, case) for case in CASES}
    for case, by_key in by_case.items():
        if not by_key:
            continue
        lines += case_table(case, by_key)
        if any(k[0] == "learned" for k in by_key):
            verdicts += verdict_table(case, by_key, random_return(out, case))
        plot_case(out, case, by_key)
    plot_overview(overview or out / "advice_budget.png", by_case)
    return "\n".join(lines + verdicts) + "\n"


# ------------------------------------------------------------------ the grid
def todo(args: argparse.Namespace) -> list[tuple[str, str, str, float, int]]:
    runs = []
    for seed in args.seeds:
        for case in args.envs:
            if "ppo" in args.learners:
                runs.append((case, "ppo", "", 1.0, seed))
            for budget in args.budgets:
                for availability in args.availability:
                    runs += [
                        (case, rule, budget, availability, seed)
                        for rule in args.learners
                        if rule != "ppo"
                    ]
    return [r for r in runs if not (args.out / "runs" / run_name(*r)).exists()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--phase", choices=("grid", "report"), default="grid")
    parser.add_argument("--envs", nargs="+", default=list(CASES), choices=CASES)
    parser.add_argument(
        "--rules", dest="learners", nargs="+", default=[*RULES, "ppo"], choices=[*RULES, "ppo"]
    )
    parser.add_argument("--budgets", nargs="+", default=list(BUDGETS))
    parser.add_argument("--availability", nargs="+", type=float, default=list(AVAILABILITY))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--episodes", type=int, default=user_envs.EVAL_EPISODES)
    parser.add_argument(
        "--tlac-setting",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a TL-AC setting for every TL-AC run, on top of the benchmark's (repeatable)",
    )
    parser.add_argument(
        "--deploy",
        choices=("greedy", "choose"),
        default="greedy",
        help="the student alone at the end: greedy (the curve's last point), or greedy or "
        "sampled, whichever scores higher on other episodes, scored on fresh ones (choose)",
    )
    parser.add_argument("--out", type=Path, default=Path("results/advice-budget"))
    parser.add_argument(
        "--overview",
        type=Path,
        default=None,
        help="where the overview figure goes (default: OUT/advice_budget.png)",
    )
    args = parser.parse_args()
    for word in args.budgets:
        try:
            budget_value(word)
        except ValueError:
            parser.error(f"--budgets takes numbers of answers or inf, got {word!r}")
    user_envs.parse_settings(args.tlac_setting)  # a malformed pair stops here, before any run
    (args.out / "runs").mkdir(parents=True, exist_ok=True)
    if args.phase == "grid":
        import torch

        torch.set_num_threads(1)
        runs = todo(args)
        print(f"{len(runs)} runs to do -> {args.out}", flush=True)
        for done, (case, learner, budget, availability, seed) in enumerate(runs, 1):
            torch.manual_seed(seed)
            if learner == "ppo":
                result = train_ppo(case, seed, args)
            else:
                result = train_tlac(case, learner, budget, availability, seed, args)
            path = args.out / "runs" / run_name(case, learner, budget, availability, seed)
            path.write_text(json.dumps(result, indent=1))
            used = "" if learner == "ppo" else f", {answers_used(result):.0f} answers"
            print(
                f"[{done}/{len(runs)}] {path.stem}: student alone {final_score(result):.2f}{used}",
                flush=True,
            )
    table = report(args.out, args.overview)
    command = shlex.join(["python", "benchmarks/advice_budget.py", *sys.argv[1:]])
    (args.out / "report.md").write_text(f"Made by `{command}`\n\n{table}")
    print(table)


if __name__ == "__main__":
    main()
