"""The teacher-quality sweep (benchmarks/teacher_sweep.py, issue 63): its teachers and its
verdicts, on hand-made cases (the sweep itself is hours of training)."""

from __future__ import annotations

import doctest
import importlib.util
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

_DIR = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(_DIR))
_spec = importlib.util.spec_from_file_location("teacher_sweep", _DIR / "teacher_sweep.py")
sweep = importlib.util.module_from_spec(_spec)
sys.modules["teacher_sweep"] = sweep  # (a dataclass looks its module up there)
_spec.loader.exec_module(sweep)


def test_the_doctests_hold():
    assert doctest.testmod(sweep).failed == 0


@pytest.mark.parametrize("env_id", ["CartPole-v1", "Pendulum-v1", "MountainCar-v0"])
def test_a_saved_teacher_acts_as_the_model_it_was_saved_from(tmp_path, env_id):
    """The acting weights alone (PPO's policy, DQN's Q-network, SAC's actor) rebuild a teacher
    whose greedy actions are the model's."""
    model = sweep.reference_model(env_id)
    with torch.no_grad():  # move the weights away from the seed's initialisation
        for p in model.policy.parameters():
            p.add_(0.1 * torch.randn_like(p))
    torch.save(sweep.acting_state(model), tmp_path / "t.pt")
    loaded = sweep.load_teacher_model(env_id, tmp_path / "t.pt")
    space = gym.make(env_id).observation_space
    space.seed(0)
    obs = np.stack([space.sample() for _ in range(32)])
    expected = model.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], expected)


def test_the_adversarial_teacher_plays_what_its_network_ranks_worst():
    ppo = sweep.reference_model("CartPole-v1")
    obs = np.array([[0.0, 0.0, 0.05, 0.3], [0.0, 0.0, -0.05, -0.3]], dtype=np.float32)
    greedy = ppo.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(sweep.Adversarial(ppo).predict(obs), 1 - greedy)  # 2 actions
    dqn = sweep.reference_model("MountainCar-v0")
    obs = np.array([[-0.5, 0.0], [-0.3, 0.02]], dtype=np.float32)
    with torch.no_grad():
        q = dqn.q_net(torch.as_tensor(obs)).numpy()
    np.testing.assert_array_equal(sweep.Adversarial(dqn).predict(obs), q.argmin(1))
    sac = sweep.reference_model("Pendulum-v1")
    obs = np.array([[1.0, 0.0, 0.5]], dtype=np.float32)
    action = sac.predict(obs, deterministic=True)[0]
    np.testing.assert_allclose(sweep.Adversarial(sac).predict(obs), -action)  # box [-2, 2]


def test_time_verdicts():
    """TL-AC at 90% in 12 s on every seed against PPO's 10 s: 1.2x; a seed of TL-AC that never
    gets there where all of PPO's do: inf; neither ever: 1. Steps are read from the curve's
    first column, seconds from its third."""
    reach = lambda seconds: {"curve": [[4096, -400.0, seconds / 2], [8192, -90.0, seconds]]}  # noqa: E731
    never = {"curve": [[4096, -400.0, 5.0], [8192, -300.0, 10.0]]}
    ours, theirs = [reach(12.0)] * 2, [reach(10.0)] * 2
    assert sweep.reach_time(ours, -100.0, "seconds") == (0, 12.0)
    assert sweep.reach_time(ours, -100.0, "steps") == (0, 8192.0)
    ratio = sweep.time_ratio(
        sweep.reach_time(ours, -100.0, "seconds"), sweep.reach_time(theirs, -100.0, "seconds")
    )
    assert ratio == pytest.approx(1.2)
    assert sweep.reach_time([reach(8.0), never], -100.0, "steps") == (1, 8192.0)
    assert sweep.time_ratio((1, 8192.0), (0, 8192.0)) == np.inf
    assert sweep.time_ratio(sweep.reach_time([never], -100.0, "steps"), (1, np.inf)) == 1.0


def test_the_reference_is_trained_again_where_its_checkpoints_are_missing(tmp_path):
    """reference/ENV.json is committed, its checkpoints are not: a fresh checkout must train
    the reference again before choosing teachers, and not once the teachers are chosen."""
    (tmp_path / "reference").mkdir()
    assert sweep.needs_reference(tmp_path, "Pendulum-v1")
    (tmp_path / "reference" / "Pendulum-v1.json").write_text("{}")
    assert sweep.needs_reference(tmp_path, "Pendulum-v1")  # the record alone is not enough
    (tmp_path / "checkpoints" / "Pendulum-v1").mkdir(parents=True)
    (tmp_path / "checkpoints" / "Pendulum-v1" / "0.pt").write_bytes(b"")
    assert not sweep.needs_reference(tmp_path, "Pendulum-v1")
    (tmp_path / "checkpoints" / "Pendulum-v1" / "0.pt").unlink()
    (tmp_path / "teachers").mkdir()
    (tmp_path / "teachers" / "Pendulum-v1.json").write_text("{}")
    assert not sweep.needs_reference(tmp_path, "Pendulum-v1")  # the teachers are saved
    with pytest.raises(SystemExit, match="run --phase reference first"):
        sweep.choose_teachers("LunarLander-v3", tmp_path, -100.0)


def test_a_doorkey_teacher_acts_as_the_ppo_it_was_saved_from_on_its_view(tmp_path):
    """DoorKey's reference is SB3 PPO on the partial view (`tlac teacher train doorkey`'s
    recipe); its saved weights make tlac's PPO teacher, which reads the student's full grid
    through that view and plays the PPO's greedy action there, and the adversarial one its
    least likely action."""
    from tlac.domains.doorkey.view import partial_view

    model = sweep.reference_model(sweep.DOORKEY)
    with torch.no_grad():
        for p in model.policy.parameters():
            p.add_(0.1 * torch.randn_like(p))
    torch.save(sweep.acting_state(model), tmp_path / "t.pt")
    teacher = sweep.load_teacher_model(sweep.DOORKEY, tmp_path / "t.pt")
    env = sweep.make_env(sweep.DOORKEY)
    grids = []
    for seed in range(8):
        obs, _ = env.reset(seed=seed)
        grids.append(obs)
    grids = np.stack(grids)
    view = partial_view(grids)
    expected = model.predict(view, deterministic=True)[0]
    np.testing.assert_array_equal(sweep.greedy_act(teacher)(grids), expected)
    with torch.no_grad():
        logits = model.policy.get_distribution(model.policy.obs_to_tensor(view)[0])
        worst = logits.distribution.logits.argmin(dim=1).numpy()
    np.testing.assert_array_equal(sweep.Adversarial(teacher).predict(grids), worst)
    assert sweep.budget(sweep.DOORKEY) == 500_000 and sweep.budget("Acrobot-v1") == 100_000


@pytest.mark.slow  # ~10 s: two PPO trainings and a student
def test_doorkey_runs_through_every_phase_on_a_tiny_budget(tmp_path, monkeypatch):
    """The reference (checkpoints of PPO on the partial view), the teachers chosen from them,
    PPO alone and a student with the domain's preset, at a few thousand steps."""
    monkeypatch.setitem(sweep.SWEEP, sweep.DOORKEY, sweep.Reference("ppo-partial", 2048, 1024))
    monkeypatch.setitem(sweep.BUDGETS, sweep.DOORKEY, 2048)
    monkeypatch.setattr(sweep, "CHOICE_EPISODES", 2)
    monkeypatch.setattr(sweep.user_envs, "EVAL_EPISODES", 2)
    for sub in ("reference", "teachers", "runs"):
        (tmp_path / sub).mkdir()
    record = sweep.train_reference(sweep.DOORKEY, tmp_path)
    assert [c[0] for c in record["checkpoints"]] == [0, 1024, 2048]
    assert all(0.0 <= c[1] <= 1.0 for c in record["checkpoints"])
    chosen = sweep.choose_teachers(sweep.DOORKEY, tmp_path, ppo_alone=0.0)
    assert set(chosen["teachers"]) == set(sweep.TEACHERS)
    for case in ("ppo", "adversarial+random"):
        run = sweep.train_run(sweep.DOORKEY, case, 0, tmp_path, every=10**6, episodes=2)
        assert run["steps"] == 2048 and 0.0 <= run["student_alone"] <= 1.0


def test_cpu_seconds_are_read_where_every_run_has_them():
    """Curve points from 2026-11-29 on carry the training process's CPU seconds (fifth column):
    the verdict reads those when every run has them, the wall clock's otherwise."""
    new = {"curve": [[4096, -400.0, 9.0, None, 3.0], [8192, -90.0, 20.0, -95.0, 6.5]]}
    old = {"curve": [[4096, -400.0, 9.0, None], [8192, -90.0, 20.0, -95.0]]}
    assert sweep.time_unit([new, new]) == "CPU seconds"
    assert sweep.time_unit([new, old]) == "seconds"
    assert sweep.reach_time([new], -100.0, "CPU seconds") == (0, 6.5)
    assert sweep.reach_time([new, old], -100.0, "seconds") == (0, 20.0)


def test_teachers_and_students_phases_say_why_they_skip_an_environment(
    tmp_path, monkeypatch, capsys
):
    """PPO alone with one seed of five: no teachers are chosen (their qualities are measured
    against its 5-seed mean) and no students run, each said in one line, not a silent 0."""
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "Pendulum-v1__ppo__seed0.json").write_text('{"student_alone": -1000.0}')
    for phase in ("teachers", "students"):
        argv = ["teacher_sweep.py", "--envs", "Pendulum-v1", "--phase", phase]
        monkeypatch.setattr(sys, "argv", [*argv, "--out", str(tmp_path)])
        sweep.main()
    out = capsys.readouterr().out
    assert "Pendulum-v1: no teachers yet: PPO alone has not run every seed [0, 1, 2, 3, 4]" in out
    assert "Pendulum-v1: no students yet: its teachers are not chosen" in out
    assert not (tmp_path / "teachers" / "Pendulum-v1.json").exists()


class _TwoFacedModel:
    """A policy whose greedy and sampled actions are told apart by the action's value (0 or 1);
    sampling draws from torch's generator, as an SB3 policy's does."""

    def predict(self, batch, deterministic=False):
        torch.rand(1)  # a draw, as a sampled policy makes
        return np.full(len(batch), 0 if deterministic else 1), None


def _fake_scores(by_seed):
    """peers.evaluate's stand-in: the score of (mode, seed) from ``by_seed``."""

    def evaluate(act, env_id, episodes, seed):
        mode = "greedy" if act(np.zeros((1, 2)))[0] == 0 else "sampled"
        return np.full(episodes, by_seed[mode, seed])

    return evaluate


def test_the_deployed_student_is_chosen_on_other_episodes_and_scored_on_the_final_ones(
    monkeypatch,
):
    final, select = sweep.user_envs.EVAL_SEED, sweep.peers.SELECT_SEED
    scores = {("greedy", final): 0.875, ("sampled", final): 0.5}  # (exact in binary)
    scores |= {("greedy", select): 0.25, ("sampled", select): 0.75}
    monkeypatch.setattr(sweep.peers, "evaluate", _fake_scores(scores))
    torch.manual_seed(0)
    deployed = sweep.deployed_alone(_TwoFacedModel(), sweep.DOORKEY)
    after = torch.rand(1)
    # sampled wins the selection, and its score is the final episodes' (not the greedy 0.875)
    assert deployed["deployed"] == "sampled" and deployed["student_alone"] == 0.5
    assert deployed["selection"] == {"greedy": 0.25, "sampled": 0.75}
    torch.manual_seed(0)  # the training's generator is left where it was
    assert torch.equal(after, torch.rand(1))
    # a tie deploys the greedy student
    scores[("greedy", select)] = 0.75
    assert sweep.deployed_alone(_TwoFacedModel(), sweep.DOORKEY)["deployed"] == "greedy"
    # elsewhere only the greedy student, scored as before
    assert sweep.deployed_alone(_TwoFacedModel(), "CartPole-v1") == {"student_alone": 0.875}


def test_a_tlac_students_deployment_is_reproducible():
    """A TL-AC model samples from its own acting generator (NumPy), not torch's: two runs of
    one seed give the same choice and scores, whatever torch's generator holds."""
    from tlac import TLAC

    results = []
    for torch_seed in (1, 2):
        model = TLAC("CartPole-v1", teachers=[], seed=0, n_steps=64)
        model.learn(128)
        torch.manual_seed(torch_seed)  # differs between the two: it must not matter
        modes = {"greedy": sweep.greedy_act(model), "sampled": sweep.peers.sampled(model)}
        results.append(sweep.peers.deployed_alone(modes, "CartPole-v1", 2))
    assert results[0] == results[1]
    assert set(results[0]["alone_by_mode"]) == {"greedy", "sampled"}
