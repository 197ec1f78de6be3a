"""What stable-baselines3 users do out of habit works on TL-AC (issue 65): SB3's own callbacks
and callbacks reading ``self.locals`` at every step, ``model.ep_info_buffer``, ``seed=None``,
one teacher without a list, an SB3 policy as a teacher, SB3's argument order refused in
one line, SB3's schedules (functions of the progress remaining, decaying to 0), a model
trained under VecNormalize used on raw observations, the student evaluated alone from Python,
and ``model.policy`` as a torch module to export."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.callbacks import (
    BaseCallback,
    ProgressBarCallback,
    StopTrainingOnMaxEpisodes,
)
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac import TLAC
from tlac.errors import ConfigError

SMALL = dict(n_steps=32, batch_size=32)
RICH_IS_EXPERIMENTAL = pytest.mark.filterwarnings("ignore:rich is experimental")


class Succeeds(gym.Wrapper):
    """CartPole that says, at the end of an episode, whether the pole stood 20 steps."""

    def reset(self, **kwargs: Any) -> Any:
        self.steps = 0
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.steps += 1
        if terminated or truncated:
            info = {**info, "is_success": self.steps >= 20}
        return obs, reward, terminated, truncated, info


def cartpole(n: int = 2) -> DummyVecEnv:
    venv = DummyVecEnv([lambda: Succeeds(gym.make("CartPole-v1")) for _ in range(n)])
    venv.seed(0)
    return venv


def left(obs: np.ndarray) -> int:
    """A poor teacher: always push left (short episodes)."""
    return 0


def model(n_envs: int = 2, **settings: Any) -> TLAC:
    torch.set_num_threads(1)
    return TLAC(cartpole(n_envs), teachers=[left], seed=0, **{**SMALL, **settings})


def same_weights(a: TLAC, b: TLAC) -> bool:
    weights = b.nets.net.state_dict()
    return all(torch.equal(w, weights[k]) for k, w in a.nets.net.state_dict().items())


class ReadsLocals(BaseCallback):
    """Keeps what SB3's collect_rollouts shows a callback at every step, and the returns it
    adds up from the rewards and dones."""

    def __init__(self) -> None:
        super().__init__()
        self.total_timesteps = None
        self.shapes: list[tuple[Any, ...]] = []
        self.n_steps: list[int] = []
        self.returns: list[float] = []
        self.rollout_ends: list[Any] = []

    def _on_training_start(self) -> None:
        self.total_timesteps = self.locals["total_timesteps"]
        self.running = np.zeros(self.training_env.num_envs)

    def _on_step(self) -> bool:
        loc = self.locals
        infos, dones, rewards = loc["infos"], loc["dones"], loc["rewards"]
        new_obs, actions = loc["new_obs"], loc["actions"]
        self.shapes.append((len(infos), dones.shape, rewards.shape, new_obs.shape, actions.shape))
        self.n_steps.append(loc["n_steps"])
        assert loc["env"] is self.training_env and loc["n_rollout_steps"] == SMALL["n_steps"]
        self.running += rewards
        for i in np.flatnonzero(dones):
            self.returns.append(float(self.running[i]))
            self.running[i] = 0.0
        return True

    def _on_rollout_end(self) -> None:
        self.rollout_ends.append(self.locals["rollout_buffer"])


def test_stop_training_on_max_episodes_stops_after_them() -> None:
    m = model(n_envs=1)
    m.learn(5000, callback=StopTrainingOnMaxEpisodes(max_episodes=3))
    assert len(m.ep_info_buffer) == 3  # stopped at the step that ended the third episode
    assert m.num_timesteps == sum(ep["l"] for ep in m.ep_info_buffer)


@RICH_IS_EXPERIMENTAL
def test_sb3_progress_bar_callback_runs() -> None:
    m = model()
    bar = ProgressBarCallback()
    m.learn(256, callback=bar)
    assert bar.pbar.total == 256 and bar.pbar.n == m.num_timesteps == 256


def test_a_callback_reads_sb3s_locals_at_every_step() -> None:
    m = model()
    seen = ReadsLocals()
    m.learn(256, callback=seen)
    assert seen.total_timesteps == 256
    assert seen.shapes == [(2, (2,), (2,), (2, 4), (2,))] * 128
    assert seen.n_steps == list(range(32)) * 4
    assert len(seen.rollout_ends) == 4 and seen.rollout_ends[-1].returns.shape == (32, 2)
    # the finished episodes' returns, as SB3 keeps them from the Monitor-style infos
    assert seen.returns and [ep["r"] for ep in m.ep_info_buffer] == seen.returns[-100:]
    assert [ep["l"] for ep in m.ep_info_buffer] == [int(r) for r in seen.returns[-100:]]
    assert list(m.ep_success_buffer) == [r >= 20 for r in seen.returns[-100:]]


@RICH_IS_EXPERIMENTAL
def test_callbacks_change_nothing_in_training() -> None:
    alone, watched = model(), model()
    alone.learn(256)
    watched.learn(256, callback=[ReadsLocals(), ProgressBarCallback()])
    assert same_weights(alone, watched)


def test_ep_info_buffer_starts_anew_as_sb3s() -> None:
    m = model()
    m.learn(128)
    kept = len(m.ep_info_buffer)
    m.learn(64, reset_num_timesteps=False)
    assert len(m.ep_info_buffer) > kept
    m.learn(64)  # reset_num_timesteps=True: a new count, new episodes, new buffers
    assert 0 < sum(ep["l"] for ep in m.ep_info_buffer) <= 64


def test_no_seed_draws_one_as_sb3_and_records_it() -> None:
    torch.set_num_threads(1)
    a, b = (TLAC(cartpole(), teachers=[left], **SMALL) for _ in range(2))
    assert a.seed != b.seed and not same_weights(a, b)
    again = TLAC(cartpole(), teachers=[left], seed=a.seed, **SMALL)  # the recorded seed repeats
    assert same_weights(again, a)
    c, d = (TLAC(cartpole(), teachers=[left], seed=7, **SMALL) for _ in range(2))
    assert c.seed == d.seed == 7 and same_weights(c, d)


class Pushes:
    """A batched teacher object: push towards where the pole leans."""

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return (obs[:, 2] + 0.5 * obs[:, 3] > 0).astype(np.int64)


def test_one_teacher_needs_no_list() -> None:
    for one, name in [(left, "left"), (Pushes(), "pushes")]:
        m = TLAC(cartpole(), teachers=one, seed=0, **SMALL)
        assert m.teacher_names == [name] and m.n_choices == 2
        m.learn(64)
        assert m.num_timesteps == 64


def test_an_sb3_policy_is_a_teacher() -> None:
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    policy = PPO("MlpPolicy", "CartPole-v1", seed=0, device="cpu").policy  # as BC gives one
    obs = np.random.default_rng(0).normal(size=(5, 4)).astype(np.float32)
    for teachers in (policy, [policy, left]):
        m = TLAC(cartpole(), teachers=teachers, seed=0, **SMALL)
        assert m.teacher_names[0] == "actorcriticpolicy"
        advice = m.teachers[0].predict(obs)
        assert np.array_equal(advice, policy.predict(obs, deterministic=True)[0])
        m.learn(64)


def test_sb3s_argument_order_is_one_clear_error() -> None:
    for call in (
        lambda: TLAC("MlpPolicy", env=cartpole()),
        lambda: TLAC("MlpPolicy", cartpole()),
    ):
        with pytest.raises(
            ConfigError, match=r"environment first .*TLAC\(env, teachers=\["
        ) as info:
            call()
        assert "policy='MlpPolicy'" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="TLAC got env twice"):
        TLAC(cartpole(), env=cartpole())


def greedy(m: TLAC, obs: np.ndarray) -> np.ndarray:
    return m.predict(obs, deterministic=True)[0]


@pytest.mark.parametrize("env_id", ["CartPole-v1", "Pendulum-v1"])
def test_get_and_set_parameters_round_trip(tmp_path, env_id: str) -> None:
    torch.set_num_threads(1)
    # normalised (auto reads Pendulum's unit-scale Box raw), so the statistics travel too
    make = lambda seed: TLAC(gym.make(env_id), seed=seed, normalize_obs=True, **SMALL)  # noqa: E731
    obs = np.stack([gym.make(env_id).observation_space.sample() for _ in range(32)])
    trained = make(0).learn(64)
    trained.deployed = trained.nets.snapshot_student(
        trained.num_timesteps
    )  # what predict deploys comes along too
    params = trained.get_parameters()
    assert params["deployed"] is not None and params["normalizer"] is not None
    other = make(1)
    assert not np.array_equal(greedy(other, obs), greedy(trained, obs))
    other.set_parameters(params)
    assert np.array_equal(greedy(other, obs), greedy(trained, obs))
    before = greedy(trained, obs)
    trained.deployed = None
    trained.learn(64)
    trained.set_parameters(params)  # a copy: the training since changed nothing in it
    assert np.array_equal(greedy(trained, obs), before)
    fresh = make(2)
    fresh.set_parameters(trained.save(tmp_path / "model"))  # or a model file
    assert np.array_equal(greedy(fresh, obs), before)


def test_set_parameters_names_what_does_not_fit() -> None:
    m = model()
    params = m.get_parameters()
    with pytest.raises(ConfigError, match=r"missing \['optimizer'\]"):
        m.set_parameters({k: v for k, v in params.items() if k != "optimizer"})
    m.set_parameters({"net": params["net"]}, exact_match=False)
    with pytest.raises(ConfigError, match=r"unknown \['policy'\]"):
        m.set_parameters({**params, "policy": {}})
    wider = TLAC(cartpole(), teachers=[left], seed=0, net_arch_low=[8, 8], **SMALL)
    with pytest.raises(ConfigError, match="does not fit this model"):
        wider.set_parameters(params)


def linear_schedule(initial: float) -> Callable[[float], float]:
    """rl-zoo's linear schedule: from ``initial`` down to 0 as the progress remaining goes
    from 1 to 0."""
    return lambda progress_remaining: progress_remaining * initial


def learning_rates(m: TLAC, steps: int) -> list[float]:
    """The learning rate of each update of ``m.learn(steps)``."""
    rates: list[float] = []
    m.learn(steps, callback=lambda m: rates.append(m.optimizer.param_groups[0]["lr"]))
    return rates


def test_sb3_schedules_decay_to_zero() -> None:
    decaying = [7.5e-4, 5e-4, 2.5e-4, 0.0]  # 4 updates of 64 steps
    by_function = model(learning_rate=linear_schedule(1e-3), clip_range=lambda p: 0.2 * p)
    assert learning_rates(by_function, 256) == pytest.approx(decaying)
    by_data = model(learning_rate={"linear": [1e-3, 0]}, clip_range={"linear": [0.2, 0.0]})
    assert learning_rates(by_data, 256) == pytest.approx(decaying)
    assert same_weights(by_function, by_data)  # the same arithmetic: p * 1e-3 either way
    with pytest.raises(ConfigError, match=r"learning_rate must be >= 0 at the end"):
        model(learning_rate={"linear": [1e-3, -1e-4]})
    with pytest.raises(ConfigError, match=r"learning_rate must be > 0, got 0"):
        model(learning_rate={"linear": [0, 1e-3]})


def test_a_schedule_factory_given_uncalled_is_one_line() -> None:
    with pytest.raises(ConfigError, match=r"returns a number, > 0 at the start \(f\(1.0\) gave <"):
        model(learning_rate=linear_schedule)  # linear_schedule(3e-4) was meant
    with pytest.raises(ConfigError, match=r"\(f\(1.0\) raised TypeError"):
        model(clip_range=lambda: 0.2)


def test_a_function_schedule_is_saved_as_its_value_then(tmp_path) -> None:
    path = tmp_path / "half.pt"

    def save_at_half(m: TLAC) -> None:
        if m.num_timesteps == 128:
            m.save(path)

    model(learning_rate=linear_schedule(1e-3)).learn(256, callback=save_at_half)
    with pytest.warns(
        UserWarning,
        match=r"saved as its value then \(learning_rate 0.0005\).*custom_objects=\{'learning_rate': f\}",
    ):
        assert TLAC.load(path).config.learning_rate == 5e-4
    f = linear_schedule(1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert TLAC.load(path, custom_objects={"learning_rate": f}).config.learning_rate is f
    with pytest.raises(ConfigError, match="saved as its value then"):
        TLAC.load(path, env=cartpole(), teachers=[left], resume=True)  # not the same schedule


def test_load_takes_sb3s_device_and_custom_objects(tmp_path) -> None:
    path = model().save(tmp_path / "m")
    for device in ("auto", "cpu", torch.device("cpu")):
        assert TLAC.load(path, device=device).num_timesteps == 0
    with pytest.raises(ConfigError, match=r"^device 'cuda': tlac runs on the CPU"):
        TLAC.load(path, device="cuda")
    changed = {"learning_rate": 1e-4, "clip_range": 0.1}
    loaded = TLAC.load(path, env=cartpole(), teachers=[left], custom_objects=changed)
    assert (loaded.config.learning_rate, loaded.config.clip_range) == (1e-4, 0.1)
    assert learning_rates(loaded, 64) == [1e-4]
    sb3s_name = TLAC.load(path, custom_objects={"lr_schedule": linear_schedule(2e-4)})
    assert sb3s_name.config.learning_rate(0.5) == 1e-4
    with pytest.raises(ConfigError, match=r"^custom_objects: unknown \['lr'\]; it takes TL-AC"):
        TLAC.load(path, custom_objects={"lr": 1e-4})
    with pytest.raises(ConfigError, match=r"^TL-AC setting learning_rate must be > 0, got -1"):
        TLAC.load(path, custom_objects={"learning_rate": -1})


def test_an_sb3_zip_is_named_as_one(tmp_path) -> None:
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    PPO("MlpPolicy", "CartPole-v1", device="cpu").save(tmp_path / "ppo")  # writes ppo.zip
    for call in (
        lambda: TLAC.load(tmp_path / "ppo"),
        lambda: TLAC.load(tmp_path / "ppo.zip"),
        lambda: model().set_parameters(str(tmp_path / "ppo.zip")),
    ):
        with pytest.raises(
            ConfigError,
            match=r"ppo.zip' is a stable-baselines3 model, not a TL-AC one: load it with its "
            r"SB3 class and pass it as a teacher, e.g. TLAC\(env, teachers=\[PPO.load\(path\)\]\)",
        ):
            call()


def test_vec_env_subproc_is_what_is_built() -> None:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    torch.set_num_threads(1)
    m = TLAC("CartPole-v1", n_envs=2, vec_env="subproc", teachers=[left], seed=0, **SMALL)
    try:
        assert isinstance(m.env.venv, SubprocVecEnv) and m.env.num_envs == 2
        m.learn(256)
        assert m.num_timesteps == 256
    finally:
        m.env.close()
    assert isinstance(TLAC("CartPole-v1", n_envs=2, seed=0, **SMALL).env.venv, DummyVecEnv)
    # an environment already made: n_envs and vec_env would be ignored, so they are refused
    with pytest.raises(ConfigError, match=r"^vec_env='subproc' is how TLAC makes the envir"):
        TLAC(gym.make("CartPole-v1"), vec_env="subproc", seed=0)
    with pytest.raises(ConfigError, match=r"^n_envs=4 .* already made, with 2: pass its id"):
        TLAC(cartpole(2), n_envs=4, seed=0)
    assert TLAC(cartpole(2), n_envs=2, vec_env="dummy", seed=0, **SMALL).n_envs == 2


class CountsChoices(BaseCallback):
    """Adds up the high level's choices of every rollout."""

    def __init__(self, n_choices: int) -> None:
        super().__init__()
        self.counts = np.zeros(n_choices)

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        choices = self.locals["rollout_buffer"].choices.reshape(-1)
        self.counts += np.bincount(choices, minlength=len(self.counts))


def test_the_progress_bars_last_shares_are_the_whole_calls(capsys) -> None:
    torch.set_num_threads(1)
    m = TLAC(cartpole(), teachers=[left, Pushes()], seed=0, **SMALL)
    counted = CountsChoices(m.n_choices)
    m.learn(512, callback=counted, progress_bar=True)
    last = capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]
    shares = counted.counts / counted.counts.sum()
    names = ["left", "pushes", "agent"]
    expected = " ".join(f"{n} {f:.0%}" for n, f in zip(names, shares, strict=True))
    assert last.endswith(f"| all 512 steps: {expected}]"), last


def test_an_sb3_teacher_under_its_own_vec_normalize_gets_normalised_observations() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from tlac.teachers.sb3 import from_sb3

    torch.set_num_threads(1)
    own = VecNormalize(cartpole(1), norm_reward=False)
    own.reset()
    for _ in range(200):  # statistics far from (0, 1)
        own.step(np.array([own.action_space.sample()]))
    agent = PPO("MlpPolicy", own, seed=0, device="cpu")
    assert agent.get_vec_normalize_env() is own
    raw = np.random.default_rng(0).normal(scale=2.0, size=(64, 4)).astype(np.float32)
    meant = agent.predict(own.normalize_obs(raw).astype(np.float32), deterministic=True)[0]
    assert not np.array_equal(meant, agent.predict(raw, deterministic=True)[0])
    for teacher in (
        TLAC(cartpole(), teachers=agent, seed=0, **SMALL).teachers[0],
        from_sb3(agent, name="ppo"),
    ):
        before = own.obs_rms.mean.copy()
        own.step(np.array([0]))  # its statistics move on; the teacher's were taken when made
        assert not np.array_equal(own.obs_rms.mean, before)
        assert np.array_equal(teacher.predict(raw), meant)
    plain = PPO("MlpPolicy", "CartPole-v1", seed=0, device="cpu")  # no VecNormalize: raw
    assert TLAC(cartpole(), teachers=plain, seed=0, **SMALL).teachers[0].normalize_obs is None


def test_a_model_trained_under_vec_normalize_loaded_without_it_normalises_raw_obs(
    tmp_path,
) -> None:
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(cartpole(2), clip_obs=5.0)
    trained = TLAC(venv, teachers=[Pushes()], seed=0, **SMALL).learn(2048)
    raw = np.random.default_rng(0).normal(scale=[1.0, 2.0, 0.2, 2.0], size=(256, 4))
    raw = raw.astype(np.float32)
    meant = greedy(trained, venv.normalize_obs(raw))  # what it acts on in training
    assert not np.array_equal(meant, greedy(trained, raw))
    path = trained.save(tmp_path / "model")
    for loaded in (TLAC.load(path), TLAC.load(path, env=gym.make("CartPole-v1"))):
        assert np.array_equal(greedy(loaded, raw), meant)  # raw observations, normalised
        assert np.array_equal(greedy(loaded, raw[0]), meant[0])
    loaded.saved_vec_normalize = None  # observations normalised by the caller
    assert np.array_equal(greedy(loaded, venv.normalize_obs(raw)), meant)
    again = TLAC.load(TLAC.load(path).save(tmp_path / "again"))  # the statistics stay
    assert np.array_equal(greedy(again, raw), meant)
    fresh = VecNormalize(cartpole(2), training=False)  # SB3's way: they are put in it
    in_env = TLAC.load(path, env=fresh)
    assert in_env.saved_vec_normalize is None and fresh.clip_obs == 5.0
    assert np.array_equal(fresh.obs_rms.mean, venv.obs_rms.mean)
    assert np.array_equal(greedy(in_env, fresh.normalize_obs(raw)), meant)
    older = torch.load(path, weights_only=True)  # a file saved before the settings were kept
    older["vec_normalize"] = {k: older["vec_normalize"][k] for k in ("obs_rms", "ret_rms")}
    torch.save(older, tmp_path / "older.pt")
    with pytest.warns(UserWarning, match=r"older.pt': the model was trained under a VecNormal"):
        assert TLAC.load(tmp_path / "older.pt").saved_vec_normalize is None


def test_student_eval_callback_logs_the_student_alone(tmp_path) -> None:
    import pandas as pd
    from stable_baselines3.common.logger import configure

    from tlac import StudentEvalCallback
    from tlac.evaluation import episode_returns

    watched = model()  # 64 steps a rollout
    watched.set_logger(configure(str(tmp_path), ["csv"]))
    evals = StudentEvalCallback(gym.make("CartPole-v1"), eval_freq=128, n_eval_episodes=2)
    watched.learn(384, callback=evals)
    assert [t for t, _, _ in evals.evaluations] == [128, 256, 384]  # after those updates
    logged = pd.read_csv(tmp_path / "progress.csv")
    assert logged["eval/student_alone_mean"].tolist() == [m for _, m, _ in evals.evaluations]
    assert logged["eval/student_alone_std"].tolist() == [s for _, _, s in evals.evaluations]
    by_hand = episode_returns(lambda o: greedy(watched, o), [gym.make("CartPole-v1")], 2, 10_000)
    assert evals.evaluations[-1][1] == by_hand.mean()  # the student alone, seeds 10000, 10001
    alone = model()
    alone.learn(384)
    assert same_weights(alone, watched)  # training unchanged
    with pytest.raises(ConfigError, match=r"eval_env must be a gymnasium\.Env, an SB3 VecEnv"):
        StudentEvalCallback(object())
    with pytest.raises(ConfigError, match="eval_freq must be a positive integer, got 0"):
        StudentEvalCallback("CartPole-v1", eval_freq=0)


def test_a_sampled_student_eval_callback_leaves_training_unchanged() -> None:
    """Sampled evaluations draw apart from the model's acting generator, from generators
    seeded with the episodes' first seed: the same weights as training without the callback,
    and the last evaluation is that of the final weights sampled so."""
    from tlac import StudentEvalCallback
    from tlac.evaluation import episode_returns, sampling_apart

    watched = model()
    evals = StudentEvalCallback(
        gym.make("CartPole-v1"), eval_freq=128, n_eval_episodes=2, deterministic=False
    )
    watched.learn(384, callback=evals)
    alone = model()
    alone.learn(384)
    assert same_weights(alone, watched)
    with sampling_apart(watched, 10_000):
        sampled = lambda o: watched.predict(o, deterministic=False)[0]  # noqa: E731
        by_hand = episode_returns(sampled, [gym.make("CartPole-v1")], 2, 10_000)
    assert evals.evaluations[-1][1] == by_hand.mean()


def test_student_eval_callback_takes_a_vec_env_as_evaluate_policy_does() -> None:
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import VecMonitor

    from tlac import StudentEvalCallback

    watched = model()
    evals = StudentEvalCallback(VecMonitor(cartpole(2)), eval_freq=128, n_eval_episodes=3)
    watched.learn(256, callback=evals)
    assert [t for t, _, _ in evals.evaluations] == [128, 256]
    by_sb3, _ = evaluate_policy(watched, seeded(VecMonitor(cartpole(2)), 10_000), 3, True, False)
    assert np.isclose(evals.evaluations[-1][1], by_sb3)  # SB3's counting, seeds 10000, 10001
    alone = model()
    alone.learn(256)
    assert same_weights(alone, watched)  # training unchanged


def test_student_eval_callback_syncs_a_vec_normalize_as_eval_callback_does() -> None:
    from stable_baselines3.common.vec_env import VecNormalize

    from tlac import StudentEvalCallback
    from tlac.evaluation import vec_episode_returns

    torch.set_num_threads(1)
    m = TLAC(VecNormalize(cartpole(2)), teachers=[Pushes()], seed=0, **SMALL)
    in_eval = VecNormalize(cartpole(1), training=False, norm_reward=True)  # its own statistics
    evals = StudentEvalCallback(in_eval, eval_freq=128, n_eval_episodes=2)
    m.learn(128, callback=evals)
    stats = m.get_vec_normalize_env()
    assert np.array_equal(in_eval.obs_rms.mean, stats.obs_rms.mean)  # synced before
    raw_returns = vec_episode_returns(  # raw observations, normalised as in training
        lambda o: greedy(m, stats.normalize_obs(o)), cartpole(1), 2, 10_000 + m.seed
    )
    assert evals.evaluations[-1][1] == raw_returns.mean()  # raw rewards too


def seeded(venv: Any, seed: int) -> Any:
    venv.seed(seed)
    return venv


JIT_TRACE_IS_DEPRECATED = pytest.mark.filterwarnings("ignore:`torch.jit.trace")


@JIT_TRACE_IS_DEPRECATED
@pytest.mark.parametrize("env_id", ["CartPole-v1", "Pendulum-v1"])
def test_model_policy_is_the_deployed_student_as_a_torch_module(env_id: str) -> None:
    torch.set_num_threads(1)
    env = gym.make(env_id)
    obs = np.stack([env.observation_space.sample() for _ in range(256)]).astype(np.float32)
    m = TLAC(env, seed=0, **SMALL).learn(128)
    live = greedy(m, obs)
    m.deployed = m.nets.snapshot_student(
        m.num_timesteps
    )  # the kept student: what predict deploys from now on
    m.learn(128)
    assert m.deployed is not None and np.array_equal(greedy(m, obs), live)
    traced = torch.jit.trace(m.policy, torch.from_numpy(obs[:8]))  # SB3's export recipe's way
    out = traced(torch.from_numpy(obs)).detach().numpy()
    if isinstance(env.action_space, gym.spaces.Discrete):
        assert np.array_equal(out.argmax(-1), live)  # the logits
    else:
        low, high = env.action_space.low, env.action_space.high
        np.testing.assert_allclose(np.clip(out, low, high), live, atol=1e-6)  # the mean
    policy_actions = m.policy.predict(obs, deterministic=True)[0]
    np.testing.assert_allclose(policy_actions, live, atol=1e-6)  # SB3's policy.predict
    assert m.policy.predict(obs[0])[0].shape == env.action_space.shape  # one, sampled


@JIT_TRACE_IS_DEPRECATED
def test_model_policy_normalises_as_predict_does(tmp_path) -> None:
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(cartpole(2))
    path = TLAC(venv, teachers=[Pushes()], seed=0, **SMALL).learn(256).save(tmp_path / "m")
    loaded = TLAC.load(path)  # predict normalises raw observations with the saved statistics
    raw = np.random.default_rng(0).normal(scale=2.0, size=(256, 4)).astype(np.float32)
    logits = torch.jit.trace(loaded.policy, torch.from_numpy(raw[:8]))(torch.from_numpy(raw))
    assert np.array_equal(logits.detach().numpy().argmax(-1), greedy(loaded, raw))
    lake = TLAC(gym.make("FrozenLake-v1"), seed=0, **SMALL)
    lake.saved_vec_normalize = loaded.saved_vec_normalize  # (no VecNormalize takes a Discrete)
    with pytest.raises(ConfigError, match=r"^model.policy applies a saved VecNormalize to Box"):
        lake.policy  # noqa: B018
    assert not hasattr(lake, "policy")  # (an AttributeError too, as for a model without one)


class DictWorld(gym.Env):
    """Ten steps of random Dict observations (a Box, a Discrete and a MultiDiscrete key);
    action 1 pays."""

    observation_space = gym.spaces.Dict(
        {
            "pos": gym.spaces.Box(-1.0, 1.0, (2,)),
            "room": gym.spaces.Discrete(3),
            "keys": gym.spaces.MultiDiscrete([2, 3]),
        }
    )
    action_space = gym.spaces.Discrete(3)

    def reset(self, seed: int | None = None, options: Any = None) -> Any:
        super().reset(seed=seed)
        self.observation_space.seed(seed)
        self.t = 0
        return self.observation_space.sample(), {}

    def step(self, action: Any) -> Any:
        self.t += 1
        return self.observation_space.sample(), float(action == 1), self.t >= 10, False, {}


def rgb_view() -> gym.Env:
    from minigrid.wrappers import ImgObsWrapper, RGBImgPartialObsWrapper

    return ImgObsWrapper(RGBImgPartialObsWrapper(gym.make("MiniGrid-Empty-5x5-v0")))


def samples(space: gym.Space, n: int) -> Any:
    """``n`` observations of ``space`` as one batch (a dict of batches for a Dict space)."""
    space.seed(0)
    drawn = [space.sample() for _ in range(n)]
    if isinstance(space, gym.spaces.Dict):
        return {key: np.stack([d[key] for d in drawn]) for key in space.spaces}
    return np.stack(drawn)


def as_tensors(obs: Any) -> Any:
    if isinstance(obs, dict):
        return {key: torch.as_tensor(value) for key, value in obs.items()}
    return torch.as_tensor(obs)


ENCODED = {
    "FrozenLake (Discrete, one-hot)": lambda: TLAC(gym.make("FrozenLake-v1"), seed=0, **SMALL),
    "Dict (Box, Discrete, MultiDiscrete keys)": lambda: TLAC(DictWorld(), seed=0, **SMALL),
    "DoorKey (integer Box, one-hot)": lambda: TLAC(
        "doorkey", teachers=["optimal"], seed=0, n_envs=1, **SMALL
    ),
    "MiniGrid RGB (CnnPolicy)": lambda: TLAC(
        rgb_view(), teachers=[lambda image: 2], policy="CnnPolicy", seed=0, **SMALL
    ),
}


@JIT_TRACE_IS_DEPRECATED
@pytest.mark.parametrize("space", list(ENCODED))
def test_model_policy_reads_encoded_observations_as_predict_does(space: str) -> None:
    torch.set_num_threads(1)
    m = ENCODED[space]().learn(64)
    m.deployed = m.nets.snapshot_student(
        m.num_timesteps
    )  # the kept student (with its own CNN copy)
    m.learn(32)
    obs = samples(m.observation_space, 16 if m.nets.obs_layout is not None else 64)
    actions = greedy(m, obs)
    few = as_tensors(obs if not isinstance(obs, dict) else {k: v[:4] for k, v in obs.items()})
    traced = torch.jit.trace(m.policy, (few,) if isinstance(obs, dict) else few[:4])
    assert np.array_equal(traced(as_tensors(obs)).detach().numpy().argmax(-1), actions)
    assert np.array_equal(m.policy.predict(obs, deterministic=True)[0], actions)
    one = {k: v[0] for k, v in obs.items()} if isinstance(obs, dict) else obs[0]
    assert m.policy.predict(one, deterministic=True)[0] == actions[0]  # one observation


def test_model_policy_exports_to_onnx(tmp_path) -> None:
    for module in ("onnx", "onnxscript", "onnxruntime"):  # torch's exporter, and to run it
        pytest.importorskip(module, reason=f"{module} is not installed (pip install {module})")
    import onnxruntime

    torch.set_num_threads(1)
    m = TLAC(gym.make("CartPole-v1"), seed=0, **SMALL).learn(64)
    obs = samples(m.observation_space, 64).astype(np.float32)
    path = tmp_path / "student.onnx"
    torch.onnx.export(  # SB3's recipe: the module from observations to actions' logits
        m.policy,
        (torch.as_tensor(obs[:2]),),
        str(path),
        input_names=["obs"],
        dynamic_shapes={"obs": {0: torch.export.Dim("batch")}},
    )
    session = onnxruntime.InferenceSession(str(path))
    logits = session.run(None, {"obs": obs})[0]
    assert np.array_equal(logits.argmax(-1), greedy(m, obs))
