"""The off-policy baselines' shared plumbing (tlac.baselines.off_policy): their behaviour is
pinned by golden hashes, and a checkpoint with the training state resumes byte-identically
(issue 10: learn N, save, load, learn N == learn 2N, for DQN-TLQL and AC-Teach on DoorKey)."""

from __future__ import annotations

import hashlib
import json
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv

from tlac.algorithms import get_algorithm
from tlac.baselines.off_policy import ReplayBuffer
from tlac.domains import get_domain, make_teachers, make_vec_env
from tlac.errors import ConfigError, TlacError
from tlac.recording import EpisodeRecorder
from tlac.run import RunSpec, resume_run, train_run
from tlac.teachers.wrappers import RandomTeacher

# sha256 (first 16 hex digits) of episodes.csv, computed on main before the shared plumbing
# (commit 8ed99d8): DoorKey, seed 3, the domain preset. Only a commit that changes what these
# algorithms compute, and says why, may update them. AC-Teach's was updated when its dropout
# masks moved from torch's Bernoulli draws to the model's NumPy generator (the same masks in
# distribution, ~5x faster; tlac.baselines.ac_teach.dropout_mask): different draws.
# One digest per machine type the project has run on (docs/architecture.md, "Golden hashes
# across machines"): a change of behaviour gives bytes that match neither.
GOLDEN = {
    "dqn-tlql": (["optimal", "random", "random"], 6000, ("53a45410632f0964", "1c1464320388c1fc")),
    "ac-teach": (["optimal", "random"], 1500, ("41f39fe26629e95a", "28b276d2aa1d9e21")),
}


@pytest.mark.parametrize("algo", list(GOLDEN))
def test_off_policy_baselines_are_pinned(tmp_path: Path, algo: str) -> None:
    teachers, steps, digests = GOLDEN[algo]
    spec = RunSpec(
        env="doorkey",
        algo=algo,
        teachers=teachers,
        steps=steps,
        seed=3,
        eval_every=None,
        eval_episodes=0,
        log_interval=500,
    )
    train_run(spec, tmp_path / "run", checkpoint_every=None)
    episodes = (tmp_path / "run" / "episodes.csv").read_bytes()
    assert hashlib.sha256(episodes).hexdigest()[:16] in digests


def test_replay_buffer_wraps_and_its_state_round_trips() -> None:
    fields = {"obs": ((2,), np.float32), "action": ((), np.int64)}
    buf = ReplayBuffer(5, fields)
    for i in range(3):
        buf.add(obs=np.full((2, 2), i, np.float32), action=np.array([i, i]))
    assert len(buf) == 5 and buf.pos == 1 and buf.full
    assert buf.arrays["action"].tolist() == [2, 0, 1, 1, 2]  # row 0 overwritten by the wrap
    copy = ReplayBuffer(5, fields)
    copy.restore(buf.state())
    a = buf.sample(np.random.default_rng(1), 7)
    b = copy.sample(np.random.default_rng(1), 7)
    assert all(torch.equal(a[k], b[k]) for k in fields)
    with pytest.raises(ConfigError, match="replay buffer does not fit"):
        ReplayBuffer(3, fields).restore(buf.state())


SMALL = {
    "dqn-tlql": dict(learning_starts=50, batch_size=16, train_freq=20, gradient_steps=2),
    "ac-teach": dict(
        batch_size=16, buffer_size=2000, cycle_env_steps=50, cycle_grad_steps=5, mc_samples=8
    ),
}


def crash_run(spec: RunSpec, folder: Path, crash_at: int, checkpoint_every: int) -> None:
    """Train ``spec`` into ``folder`` and crash at the first evaluation at or after
    ``crash_at`` steps, as a killed run would: a checkpoint is left, no result."""

    class Crash(Exception):
        pass

    def crash(timestep: int, student: float, train_return: float) -> None:
        if timestep >= crash_at:
            raise Crash

    with pytest.raises(Crash):
        train_run(spec, folder, on_eval=crash, checkpoint_every=checkpoint_every)
    assert (folder / "checkpoint.pt").exists() and not (folder / "result.json").exists()


def _doorkey(algo: str, seed: int = 4):
    """A fresh model of ``algo`` on DoorKey with an optimal and a random teacher (the random
    one has a generator, which the checkpoint must carry)."""
    domain = get_domain("doorkey")
    env = make_vec_env(domain, 1, seed, None)
    teachers = make_teachers(domain, ["optimal", "random"], domain.make_env(), seed)
    return get_algorithm(algo)(env, teachers=teachers, seed=seed, **SMALL[algo])


def _pendulum_ac_teach(seed: int = 4):
    venv = DummyVecEnv([lambda: gym.make("Pendulum-v1")])
    venv.seed(seed)
    box = gym.spaces.Box(-2.0, 2.0, (1,), np.float32)
    teachers = [RandomTeacher(box, seed=seed, name="random")]
    algo = get_algorithm("ac-teach")
    return algo(EpisodeRecorder(venv), teachers=teachers, seed=seed, **SMALL["ac-teach"])


def _digest(model) -> str:
    h = hashlib.sha256()
    for name in ("q_high", "q_low", "critic", "actor"):
        net = getattr(model, name, None)
        for p in [] if net is None else net.parameters():
            h.update(p.detach().numpy().tobytes())
    h.update(np.array(list(model.env.episode_returns)).tobytes())
    h.update(str((model.env.episodes_done, model.num_timesteps)).encode())
    return h.hexdigest()


@pytest.mark.parametrize(
    ("algo", "make"),
    [
        ("dqn-tlql", lambda: _doorkey("dqn-tlql")),
        ("ac-teach", lambda: _doorkey("ac-teach")),
        ("ac-teach", _pendulum_ac_teach),
    ],
    ids=["dqn-tlql-doorkey", "ac-teach-doorkey", "ac-teach-pendulum"],
)
def test_learn_n_save_load_learn_n_equals_learn_2n(tmp_path: Path, algo: str, make) -> None:
    """A call of 2n steps stopped after n, saved with its training state, loaded and given
    the remaining steps, ends byte-identical to the uninterrupted call: the exploration
    schedule, the replay buffer, the generators, the teachers' generators, the followed
    policies (AC-Teach) and the episodes in progress all continue."""
    n = 300
    straight = make()
    straight.learn(2 * n)

    first = make()
    first.learn(2 * n, callback=lambda m: m.num_timesteps < n)
    assert n <= first.num_timesteps < 2 * n
    path = first.save(tmp_path / "ck", training_state=True)
    again = make()  # a fresh env and fresh teachers, as a new process would build them
    cls = get_algorithm(algo)
    resumed = cls.load(path, env=again.env, teachers=again.teachers, resume=True)
    resumed.learn(2 * n - resumed.num_timesteps)
    assert _digest(resumed) == _digest(straight)

    # without the training state the continuation differs (so the test can fail)
    other = make()
    plain = cls.load(first.save(tmp_path / "plain"), env=other.env, teachers=other.teachers)
    plain.learn(2 * n - plain.num_timesteps)
    assert _digest(plain) != _digest(straight)
    with pytest.raises(ConfigError, match="holds no training state"):
        cls.load(tmp_path / "plain.pt", env=other.env, teachers=other.teachers, resume=True)


def test_load_rejects_another_algorithm_and_mismatched_spaces(tmp_path: Path) -> None:
    dqn = _doorkey("dqn-tlql")
    path = dqn.save(tmp_path / "dqn")
    with pytest.raises(ConfigError, match="is not a ac-teach model file"):
        get_algorithm("ac-teach").load(path)
    pend = _pendulum_ac_teach()
    with pytest.raises(ConfigError, match=r"observation space .* does not match the model's"):
        get_algorithm("dqn-tlql").load(path, env=pend.env)


@pytest.mark.parametrize("algo", ["dqn-tlql", "ac-teach"])
def test_an_interrupted_baseline_run_resumes_exactly(tmp_path: Path, algo: str) -> None:
    """As tests/test_cli.py's TL-AC case: a run stopped after a checkpoint and resumed ends
    with the same run files as an uninterrupted run (progress.csv without its clock rows)."""
    spec = RunSpec(
        env="doorkey",
        algo=algo,
        teachers=["optimal", "random"],
        steps=900,
        seed=2,
        eval_every=300,
        eval_episodes=2,
        log_interval=150,
        overrides=SMALL[algo],
    )
    straight, broken = tmp_path / "straight", tmp_path / "broken"
    train_run(spec, straight, checkpoint_every=300)
    crash_run(spec, broken, crash_at=600, checkpoint_every=300)
    resume_run(broken, checkpoint_every=300)
    assert_same_run_files(broken, straight)
    with pytest.raises(TlacError, match="finished run"):
        resume_run(broken)


WALL_CLOCK = {"result.json": ("wall_time_s", "steps_per_s")}


def assert_same_run_files(folder: Path, reference: Path) -> None:
    """Every file of two run folders byte-identical, model.pt included, except the wall-clock
    fields (docs/architecture.md): progress.csv's time/* rows, monitor.csv's start time and
    t column, result.json's wall_time_s and steps_per_s."""
    names = sorted(p.name for p in reference.iterdir() if p.is_file())
    assert names == sorted(p.name for p in folder.iterdir() if p.is_file())
    for name in names:
        got, want = (
            (folder / name).read_text(errors="replace"),
            (reference / name).read_text(errors="replace"),
        )
        if name == "progress.csv":
            got, want = ([ln for ln in t.splitlines() if ",time/" not in ln] for t in (got, want))
        elif name == "monitor.csv":
            got, want = ([ln.rsplit(",", 1)[0] for ln in t.splitlines()[1:]] for t in (got, want))
        elif name == "result.json":
            got, want = (
                {k: v for k, v in json.loads(t).items() if k not in WALL_CLOCK[name]}
                for t in (got, want)
            )
        else:
            got, want = (folder / name).read_bytes(), (reference / name).read_bytes()
        assert got == want, name


@pytest.mark.parametrize("algo", ["tlac", "ac-teach"])
def test_a_run_on_a_simulation_no_pickle_holds_resumes_exactly(tmp_path: Path, algo: str) -> None:
    """PyBullet's simulation lives in its physics server, which no checkpoint can hold: the
    episodes in progress are re-created in fresh environments from their resets and actions,
    and the resumed hopper-bullet run ends with the files of the uninterrupted one."""
    overrides = SMALL["ac-teach"] if algo == "ac-teach" else dict(n_epochs=1)
    spec = RunSpec(
        env="hopper-bullet",
        algo=algo,
        teachers=["random"],
        steps=960,
        seed=1,
        eval_every=320,
        eval_episodes=1,
        log_interval=160,
        overrides=overrides,
    )
    straight, broken = tmp_path / "straight", tmp_path / "broken"
    train_run(spec, straight, checkpoint_every=320)
    crash_run(spec, broken, crash_at=640, checkpoint_every=320)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # no "starts new episodes"
        resume_run(broken, checkpoint_every=320)
    assert_same_run_files(broken, straight)
    ends = [int(line.split(",")[0]) for line in (broken / "episodes.csv").read_text().split()[1:]]
    assert ends[0] < 320 < ends[-1]  # episodes on both sides of the resume
