"""SB3 callbacks in tlac's own learn loops (issue 11): EvalCallback, CheckpointCallback, lists
mixing them with plain functions, and a callback that stops training; for TL-AC, DQN-TLQL,
AC-Teach and the SB3 baselines."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac import TLAC
from tlac.algorithms import get_algorithm
from tlac.errors import ConfigError
from tlac.recording import EpisodeRecorder
from tlac.teachers.base import as_teacher


def cartpole(n: int = 2) -> EpisodeRecorder:
    venv = DummyVecEnv([lambda: gym.make("CartPole-v1") for _ in range(n)])
    venv.seed(0)
    return EpisodeRecorder(venv)


def balance_teacher():
    return as_teacher(lambda o: int(o[2] + 0.5 * o[3] > 0), gym.spaces.Discrete(2), name="pd")


SMALL = {
    "tlac": dict(n_steps=16, batch_size=32),
    "dqn-tlql": dict(learning_starts=50, batch_size=16, train_freq=10, gradient_steps=1),
    "ac-teach": dict(
        batch_size=16, buffer_size=2000, cycle_env_steps=50, cycle_grad_steps=2, mc_samples=4
    ),
    "ppo": dict(n_steps=32, batch_size=32),
}


@pytest.mark.parametrize("algo", list(SMALL))
def test_eval_and_checkpoint_callbacks_and_functions_run(tmp_path: Path, algo: str) -> None:
    teachers = [] if algo == "ppo" else [balance_teacher()]
    model = get_algorithm(algo)(cartpole(), teachers=teachers, seed=0, **SMALL[algo])
    eval_env = DummyVecEnv([lambda: gym.make("CartPole-v1")])
    evaluate = EvalCallback(
        eval_env,
        eval_freq=100,
        n_eval_episodes=2,
        best_model_save_path=str(tmp_path / "best"),
        log_path=str(tmp_path / "evals"),
        verbose=0,
    )
    checkpoint = CheckpointCallback(save_freq=200, save_path=str(tmp_path / "ck"))
    calls: list[int] = []
    model.learn(600, callback=[evaluate, checkpoint, lambda m: calls.append(m.num_timesteps)])
    # about 600 steps over 2 envs = 300 vectorised steps: evaluations at 100, 200, 300 calls
    assert len(evaluate.evaluations_timesteps) == 3
    assert np.isfinite(evaluate.last_mean_reward) and evaluate.last_mean_reward > 0
    assert any((tmp_path / "best").iterdir())  # the best model, saved by the model's own save
    assert len(list((tmp_path / "ck").iterdir())) >= 1
    assert calls and calls[-1] == model.num_timesteps


class StopAfter(BaseCallback):
    def __init__(self, calls: int):
        super().__init__()
        self.limit, self.ended = calls, False

    def _on_step(self) -> bool:
        return self.n_calls < self.limit

    def _on_training_end(self) -> None:
        self.ended = True


@pytest.mark.parametrize("algo", ["tlac", "dqn-tlql", "ac-teach"])
def test_an_sb3_callback_returning_false_stops_training(algo: str) -> None:
    model = get_algorithm(algo)(cartpole(), teachers=[balance_teacher()], seed=0, **SMALL[algo])
    stop = StopAfter(40)  # 40 vectorised steps = 80 environment steps
    model.learn(2000, callback=stop)
    assert model.num_timesteps < 400 and stop.ended and stop.n_calls == 40
    assert stop.model is model and stop.training_env is model.get_env()


def test_a_bad_callback_is_one_clear_error() -> None:
    model = TLAC(cartpole(), teachers=[balance_teacher()], seed=0, **SMALL["tlac"])
    with pytest.raises(ConfigError, match="callback must be a function f\\(model\\)"):
        model.learn(64, callback="every step")


def test_predict_has_sb3s_signature_and_default() -> None:
    model = TLAC(cartpole(), teachers=[balance_teacher()], seed=0, **SMALL["tlac"])
    obs = model.get_env().reset()
    greedy, state = model.predict(obs, state=None, episode_start=np.ones(2), deterministic=True)
    assert state is None and greedy.shape == (2,)
    # SB3's default is a sampled action: over many draws both actions appear
    draws = np.stack([model.predict(obs)[0] for _ in range(50)])
    assert len(np.unique(draws)) == 2


def test_sb3_style_constructor_arguments(tmp_path: Path, capsys) -> None:
    import torch

    torch.set_num_threads(2)
    model = TLAC(
        cartpole(),
        teachers=[balance_teacher()],
        seed=0,
        verbose=1,
        tensorboard_log=str(tmp_path / "tb"),
        device="cpu",
        **SMALL["tlac"],
    )
    model.learn(2048, progress_bar=False)
    printed = capsys.readouterr().out
    assert "explained_variance" in printed and "ep_rew_mean" in printed  # SB3 table
    assert list((tmp_path / "tb" / "TLAC_1").glob("events.out.tfevents.*"))
    assert torch.get_num_threads() == 1  # learn sets one thread: fastest for small networks
    for bad, match in [
        ({"device": "cuda"}, "tlac runs on the CPU"),
        ({"verbose": "loud"}, "verbose must be 0, 1 or 2"),
        ({"torch_threads": 0}, "torch_threads must be a positive integer"),
    ]:
        with pytest.raises(ConfigError, match=match):
            TLAC(cartpole(), teachers=[balance_teacher()], **bad)


def test_n_envs_from_a_domain_name_can_run_in_subprocesses(tmp_path: Path) -> None:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from tlac.run import RunSpec, train_run

    model = TLAC("doorkey", teachers=["optimal"], seed=0, n_envs=2, vec_env="subproc")
    try:
        assert isinstance(model.env.venv, SubprocVecEnv)
        model.learn(128, progress_bar=False)
        assert model.num_timesteps >= 128
    finally:
        model.env.close()
    spec = RunSpec(env="doorkey", steps=64, overrides={"vec_env": "subproc"})
    with pytest.raises(ConfigError, match="vec_env=subproc is for the Python API"):
        train_run(spec, tmp_path / "run")
    assert not (tmp_path / "run").exists()  # refused before anything is written


def test_policy_kwargs_as_in_sb3() -> None:
    model = TLAC(
        cartpole(),
        teachers=[balance_teacher()],
        policy_kwargs={"net_arch": {"pi": [32, 32], "vf": [16, 16]}},
        net_arch_critic=[8, 8],  # a setting given by name wins
        **SMALL["tlac"],
    )
    cfg = model.config
    assert cfg.net_arch_high == [32, 32] and cfg.net_arch_low == [32, 32]
    assert cfg.net_arch_critic == [8, 8]
    with pytest.raises(ConfigError, match="not supported by TL-AC"):
        TLAC(cartpole(), policy_kwargs={"activation_fn": "relu"})
