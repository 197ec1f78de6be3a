"""How a run deploys its student: greedy, sampled, or the better of the two (``--deploy``).

The choice is made on the evaluations' episodes and the chosen mode is scored again on fresh
ones; sampled evaluations draw apart from the model's generators, so training is unchanged."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from tlac import TLAC
from tlac.cli import main
from tlac.domains import get_domain
from tlac.errors import ConfigError
from tlac.evaluation import evaluate_student
from tlac.run import RunSpec, eval_row, train_run

SPEC = dict(teachers=["optimal", "random"], steps=2048, seed=3, eval_every=512, eval_episodes=2)
"""Evaluations at steps 0, 512, 1024, 1536 and 2048 on seeds 10_003, ...; the deployed
student's fresh one on seeds 30_003, ..."""


def _script(monkeypatch, scores: dict[tuple[int, str], list[float]]) -> list[tuple[int, str]]:
    """Replace tlac.run's evaluations by ``scores[(seed, mode)]`` in turn; returns the
    (seed, mode) of every evaluation asked for, in order."""
    import tlac.run as run_module

    left = {key: iter(values) for key, values in scores.items()}
    asked: list[tuple[int, str]] = []

    def scripted(model, domain, episodes, seed, deterministic=True):
        key = (seed, "greedy" if deterministic else "sampled")
        asked.append(key)
        return np.full(episodes, next(left[key]))

    monkeypatch.setattr(run_module, "evaluate_student", scripted)
    return asked


def test_eval_row_counts_the_higher_mode_and_greedy_on_a_tie():
    tie = eval_row(0, {"greedy": np.array([0.5, 0.5]), "sampled": np.array([1.0, 0.0])})
    assert tie == (0, 0.5, 0.0, 2, "greedy", 0.5, 0.5)
    higher = eval_row(7, {"greedy": np.array([0.2]), "sampled": np.array([0.3])})
    assert higher == (7, 0.3, 0.0, 1, "sampled", 0.2, 0.3)


def test_choose_with_keep_best_deploys_the_best_evaluation_in_its_mode(tmp_path, monkeypatch):
    """Every evaluation scores both modes; the best (step, mode) is deployed and scored again
    in that mode on fresh episodes; eval.csv names each row's mode."""
    asked = _script(
        monkeypatch,
        {
            (10_003, "greedy"): [0.1, 0.2, 0.4, 0.2, 0.3],
            (10_003, "sampled"): [0.0, 0.5, 0.4, 0.3, 0.1],
            (30_003, "sampled"): [0.45],
        },
    )
    out = tmp_path / "run"
    result = train_run(RunSpec(**SPEC, keep_best=True, deploy="choose"), out)
    assert asked[-1] == (30_003, "sampled") and len(asked) == 11
    assert result["deploy_mode"] == "sampled" and result["deployed_from_step"] == 512
    assert result["deployed_selection_mean"] == 0.5 and result["final_eval_mean"] == 0.45
    assert result["last_eval_mean"] == 0.3  # step 2048: greedy 0.3 against sampled 0.1
    assert TLAC.load(out / "model").num_timesteps == 512
    rows = (out / "eval.csv").read_text().splitlines()
    assert rows[0] == "timestep,mean_return,std_return,episodes,mode,greedy_mean,sampled_mean"
    assert [r.split(",")[4] for r in rows[1:]] == [
        "greedy",
        "sampled",
        "greedy",
        "sampled",
        "greedy",
    ]
    logged = [line.split(",") for line in (out / "progress.csv").read_text().splitlines()]
    by_key = lambda key: [float(r[2]) for r in logged if r[1] == key]  # noqa: E731
    assert by_key("eval/student_alone_mean") == [0.1, 0.5, 0.4, 0.3, 0.3]
    assert by_key("eval/greedy_mean") == [0.1, 0.2, 0.4, 0.2, 0.3]
    assert by_key("eval/sampled_mean") == [0.0, 0.5, 0.4, 0.3, 0.1]
    assert by_key("eval/deploys_sampled") == [0.0, 1.0, 0.0, 1.0, 0.0]


def test_choose_without_keep_best_takes_the_last_evaluations_mode(tmp_path, monkeypatch):
    asked = _script(
        monkeypatch,
        {
            (10_003, "greedy"): [0.1, 0.2, 0.3, 0.2, 0.3],
            (10_003, "sampled"): [0.0, 0.5, 0.1, 0.1, 0.6],
            (30_003, "sampled"): [0.55],
        },
    )
    result = train_run(RunSpec(**SPEC, deploy="choose"), tmp_path / "run")
    assert asked[-1] == (30_003, "sampled")
    assert result["deploy_mode"] == "sampled" and "deployed_from_step" not in result
    assert result["deployed_selection_mean"] == 0.6 and result["final_eval_mean"] == 0.55


def test_sampled_and_greedy_runs_score_one_mode_without_a_fresh_rescoring(tmp_path, monkeypatch):
    for mode in ("sampled", "greedy"):
        asked = _script(monkeypatch, {(10_003, mode): [0.1, 0.2, 0.3, 0.2, 0.25]})
        result = train_run(RunSpec(**SPEC, deploy=mode), tmp_path / mode)
        assert asked == [(10_003, mode)] * 5
        assert result["deploy_mode"] == mode and result["final_eval_mean"] == 0.25
        assert "deployed_selection_mean" not in result


def test_training_is_the_same_whatever_the_deployment(tmp_path):
    """The sampled evaluations draw apart from the model's generators: the episodes of
    training are byte-identical under every mode."""
    spec = dict(SPEC, steps=1536)
    episodes = {}
    for mode in ("greedy", "sampled", "choose"):
        out = tmp_path / mode
        train_run(RunSpec(**spec, deploy=mode), out)
        episodes[mode] = (out / "episodes.csv").read_bytes()
    assert episodes["greedy"] == episodes["sampled"] == episodes["choose"]
    assert len(episodes["greedy"].splitlines()) > 10


def test_a_sampled_evaluation_is_seeded_and_leaves_the_generators_as_they_were():
    """An untrained CartPole student, whose sampled episodes differ with the draws."""
    model = TLAC("CartPole-v1", teachers=None, seed=0)
    domain = get_domain("CartPole-v1")
    acting = model.rng.bit_generator.state
    torch_state = torch.random.get_rng_state()
    first = evaluate_student(model, domain, 3, seed=5, deterministic=False)
    again = evaluate_student(model, domain, 3, seed=5, deterministic=False)
    other = evaluate_student(model, domain, 3, seed=6, deterministic=False)
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    assert model.rng.bit_generator.state == acting
    assert torch.equal(torch.random.get_rng_state(), torch_state)


def test_tlac_eval_acts_as_the_run_deploys(tmp_path, capsys):
    out = tmp_path / "run"
    base = ["train", "--steps", "64", "--no-progress", "--eval-episodes", "1", "--out", str(out)]
    assert main([*base, "--deploy", "sampled"]) == 0
    assert json.loads((out / "result.json").read_text())["deploy_mode"] == "sampled"
    assert "student alone (no teachers, sampled" in capsys.readouterr().out
    for flags, mode in (([], "sampled"), (["--greedy"], "greedy"), (["--stochastic"], "sampled")):
        assert main(["eval", str(out), "--episodes", "2", "--json", *flags]) == 0
        assert json.loads(capsys.readouterr().out)["mode"] == mode, flags


def test_bad_deploy_values_name_the_choices():
    with pytest.raises(ConfigError, match=r"unknown deploy 'best'.*greedy, sampled, choose"):
        RunSpec(env="doorkey", deploy="best").validate()
    with pytest.raises(ConfigError, match="give eval_episodes > 0"):
        RunSpec(env="doorkey", deploy="choose", eval_episodes=0).validate()
    with pytest.raises(ConfigError, match="dqn-tlql's student acts greedily only"):
        RunSpec(env="doorkey", algo="dqn-tlql", deploy="sampled").validate()
    from tlac.experiments.config import EvalSchedule

    with pytest.raises(ConfigError, match=r"field 'deploy'.*one of greedy, sampled, choose"):
        EvalSchedule(deploy="best")
    with pytest.raises(ConfigError, match=r"field 'deploy'.*greedy or sampled with episodes: 0"):
        EvalSchedule(deploy="choose", episodes=0)
    with pytest.raises(SystemExit) as stop:
        main(["train", "--deploy", "best"])
    assert stop.value.code == 2


@pytest.mark.parametrize(
    "field, old_value, new_value", [("deploy", "greedy", "choose"), ("keep_best", False, True)]
)
def test_runs_made_before_a_setting_read_as_its_old_value(tmp_path, field, old_value, new_value):
    """A config.yaml without ``deploy`` was written by a greedy run, one without
    ``keep_best`` by a run that kept its last weights: the same command continues it, and a
    grid asking for another value is told that it differs."""
    import yaml

    from tlac.experiments.runner import spec_mismatch
    from tlac.run import _same_settings, resolve_run

    run = resolve_run(RunSpec(**SPEC))
    out = tmp_path / "run"
    out.mkdir()
    config = {k: v for k, v in dataclasses.asdict(run.spec).items() if k != field}
    config.update(teacher_kinds=run.teacher_kinds, preset=run.preset)
    (out / "config.yaml").write_text(yaml.safe_dump(config))
    other = RunSpec(**SPEC, **{field: new_value})
    assert _same_settings(out, run)
    assert not _same_settings(out, resolve_run(other))
    old = (out / "config.yaml").read_bytes()
    assert spec_mismatch(RunSpec(**SPEC), old) is None
    assert spec_mismatch(other, old) == f"{field}={old_value!r} (now {new_value!r})"
