"""SB3's API where an SB3 user reaches for it (issue 43, point 2): make a Gymnasium id,
seed=None, learn's keyword arguments and defaults, set_env, save's file name, and a clear
error for what a tlac model file cannot hold."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac import TLAC
from tlac.errors import ConfigError
from tlac.two_level.config import TLACConfig

SMALL = dict(n_steps=16, batch_size=16)


def test_a_gymnasium_id_is_made_as_sb3_makes_it() -> None:
    model = TLAC("CartPole-v1", seed=0, n_envs=2, **SMALL)
    assert isinstance(model.get_env(), DummyVecEnv) and model.get_env().num_envs == 2
    with pytest.raises(
        ConfigError, match=r"neither a tlac domain .* nor a registered Gymnasium id"
    ):
        TLAC("CartPol-v1")


def test_seed_none_draws_a_recorded_seed() -> None:
    seeds = {TLAC("CartPole-v1", seed=None, **SMALL).seed for _ in range(3)}
    assert len(seeds) == 3 and all(0 <= s < 2**31 for s in seeds)


def test_learn_takes_sb3s_keywords_and_resets_the_count_by_default(tmp_path) -> None:
    model = TLAC("CartPole-v1", seed=0, tensorboard_log=str(tmp_path), **SMALL)
    model.learn(64, log_interval=32, tb_log_name="run")
    assert model.num_timesteps == 64 and model.log_interval == 32
    assert [p.name for p in tmp_path.iterdir()] == ["run_1"]
    model.learn(32, reset_num_timesteps=False)
    assert model.num_timesteps == 96
    model.learn(32)  # SB3's default: a new count
    assert model.num_timesteps == 32
    with pytest.raises(ConfigError, match="reset_num_timesteps: expected True or False"):
        model.learn(32, reset_num_timesteps="no")
    with pytest.raises(ConfigError, match="log_interval: expected a positive number of steps"):
        model.learn(32, log_interval=0)


def test_set_env_and_save_names(tmp_path) -> None:
    model = TLAC("CartPole-v1", seed=0, **SMALL)
    other = DummyVecEnv([lambda: gym.make("CartPole-v1")])
    model.set_env(other)
    assert model.get_env() is other and model._last_obs is None
    model.learn(32)
    with pytest.raises(ConfigError, match=r"action space|observation space"):
        model.set_env(gym.make("MountainCarContinuous-v0"))
    with pytest.raises(ConfigError, match="steps 1 environments at a time, got 2"):
        model.set_env(DummyVecEnv([lambda: gym.make("CartPole-v1")] * 2))
    assert model.save(tmp_path / "x.zip") == tmp_path / "x.zip"  # SB3 writes the name given
    assert model.save(tmp_path / "x") == tmp_path / "x.pt"
    assert TLAC.load(tmp_path / "x.zip").num_timesteps == 32


def test_sb3_callbacks_without_spurious_warnings(tmp_path, recwarn) -> None:
    eval_env = DummyVecEnv([lambda: gym.make("CartPole-v1")])
    model = TLAC(DummyVecEnv([lambda: gym.make("CartPole-v1")]), seed=0, **SMALL)
    evaluation = EvalCallback(eval_env, eval_freq=32, n_eval_episodes=1)
    model.learn(64, callback=[evaluation, CheckpointCallback(32, str(tmp_path))])
    assert not [w for w in recwarn if "not of the same type" in str(w.message)]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "rl_model_32_steps.zip",
        "rl_model_64_steps.zip",
    ]


def test_the_headline_figures_reach_the_logs(tmp_path) -> None:
    """teacher/* shares reach SB3's logger (TensorBoard) from Python; a run folder's
    config.yaml holds every resolved setting and progress.csv the student-alone evaluation
    (issue 43, point 3)."""
    import csv

    import yaml
    from stable_baselines3.common.logger import Logger

    from tlac.run import RunSpec, train_run

    recorded: dict[str, float] = {}

    class Keep(Logger):
        def record(self, key, value, exclude=None):
            recorded[key] = value

        def dump(self, step=0):
            pass

    model = TLAC("CartPole-v1", teachers=[lambda o: int(o[2] > 0)], seed=0, verbose=1, **SMALL)
    model.set_logger(Keep(folder=None, output_formats=[]))
    model.learn(64, log_interval=32)
    assert {"teacher/teacher0", "teacher/agent"} <= set(recorded)
    assert abs(recorded["teacher/teacher0"] + recorded["teacher/agent"] - 1.0) < 1e-9

    out = tmp_path / "run"
    train_run(RunSpec(env="doorkey", steps=64, eval_every=64, eval_episodes=1), out)
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["settings"]["variant"] == "graduate"
    assert {f.name for f in dataclasses.fields(TLACConfig)} <= set(config["settings"])
    rows = list(csv.reader((out / "progress.csv").open()))
    assert {"eval/student_alone_mean", "eval/student_alone_std"} <= {r[1] for r in rows}
