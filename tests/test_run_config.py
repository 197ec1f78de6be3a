"""A run is worked out once (tlac.run.resolve_run): one ``tlac train`` parses each teacher
once and builds TLACConfig once. Its folder's config.yaml records the run as it ran:
``settings`` (the model's resolved settings) and ``hyperparameters`` agree on the number of
environments, which is what the run stepped (issue 64: settings.n_envs was 1 beside
hyperparameters.n_envs 4)."""

from __future__ import annotations

import csv

import pytest
import yaml

import tlac.domains
from tlac.cli import main
from tlac.run import RunSpec, train_run
from tlac.two_level.config import TLACConfig


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


def test_one_tlac_train_parses_each_teacher_once_and_builds_tlacconfig_once(
    tmp_path, monkeypatch
) -> None:
    parsed: list[str] = []
    built: list[TLACConfig] = []
    parse, init = tlac.domains.parse_teacher_spec, TLACConfig.__init__

    def counting_parse(domain, spec):
        parsed.append(spec)
        return parse(domain, spec)

    def counting_init(self, *args, **kwargs):
        built.append(self)
        init(self, *args, **kwargs)

    monkeypatch.setattr(tlac.domains, "parse_teacher_spec", counting_parse)
    monkeypatch.setattr(TLACConfig, "__init__", counting_init)
    out = tmp_path / "run"
    args = ["train", "--env", "doorkey", "--teachers", "optimal,random:0.5,random"]
    args += ["--steps", "64", "--set", "n_envs=2", "--eval-episodes", "1"]
    assert main([*args, "--out", str(out), "--no-progress"]) == 0
    assert parsed == ["optimal", "random:0.5", "random"]
    assert len(built) == 1
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["settings"]["n_envs"] == config["hyperparameters"]["n_envs"] == 2
