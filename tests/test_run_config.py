"""A run folder's config.yaml records the run as it ran: ``settings`` (the model's resolved
settings) and ``hyperparameters`` agree on the number of environments, which is what the
run stepped (issue 64: settings.n_envs was 1 beside hyperparameters.n_envs 4)."""

from __future__ import annotations

import csv

import pytest
import yaml

from tlac.run import RunSpec, train_run


@pytest.mark.parametrize("n_envs", [1, 3])
def test_config_yaml_records_n_envs_as_run(tmp_path, n_envs: int) -> None:
    spec = RunSpec(
        env="doorkey",
        teachers=["optimal"],
        steps=16 * n_envs,
        overrides={"n_envs": n_envs},
        eval_episodes=1,
    )
    out = tmp_path / "run"
    train_run(spec, out)
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["hyperparameters"]["n_envs"] == n_envs
    assert config["settings"]["n_envs"] == n_envs
    assert next(iter(config["hyperparameters"])) == "n_envs"  # where it always was
    with (out / "progress.csv").open() as f:  # one rollout of n_steps (16) in each env
        steps = {int(float(row[0])) for row in csv.reader(f) if row[0][0].isdigit()}
    assert max(steps) == 16 * n_envs
