"""The `tlac` command: a short real run, evaluation, and one-line errors with exit status 2."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tlac.cli import main
from tlac.errors import TlacError


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "tlac.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_train_then_eval(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(
        [
            "train",
            "--env",
            "doorkey",
            "--teachers",
            "optimal,random,random",
            "--steps",
            "600",
            "--seed",
            "0",
            "--out",
            str(out),
            "--no-progress",
            "--eval-episodes",
            "2",
            "--log-interval",
            "200",
        ]
    )
    assert code == 0
    for name in (
        "config.yaml",
        "episodes.csv",
        "teacher_usage.csv",
        "eval.csv",
        "model.pt",
        "result.json",
    ):
        assert (out / name).exists(), name
    header = (out / "episodes.csv").read_text().splitlines()[0]
    assert header.startswith("timestep,return,length")
    result = json.loads((out / "result.json").read_text())
    assert result["steps"] >= 600
    # SB3 / rl-zoo tools read the run folder: monitor.csv holds the same episodes
    from stable_baselines3.common.monitor import load_results

    monitor = load_results(str(out))
    episodes = (out / "episodes.csv").read_text().splitlines()[1:]
    assert len(monitor) == len(episodes) >= 1
    assert monitor["r"].tolist() == [float(ln.split(",")[1]) for ln in episodes]
    keys = {ln.split(",")[1] for ln in (out / "progress.csv").read_text().splitlines()[1:]}
    sb3_keys = {"ep_len_mean", "explained_variance", "clip_fraction", "n_updates"}
    assert {k.split("/")[1] for k in keys} >= sb3_keys
    capsys.readouterr()
    assert main(["eval", str(out), "--episodes", "3", "--json", "--with-teachers"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert (
        printed["episodes"] == 3 and "student_mean" in printed and "with_teachers_mean" in printed
    )


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["train", "--env", "atari"], "unknown environment 'atari'"),
        (["train", "--env", "CartPole-v1"], "'CartPole-v1' is a Gymnasium id, with no teachers"),
        (["train", "--env", "CartPole-v1", "--teachers", "none.py:pd"], "no such file 'none.py'"),
        (["train", "--env", "CartPole-v1", "--teachers", "agent.zip:2"], "outside [0, 1]"),
        (["train", "--teachers", "optimal,wizard"], "unknown teacher for doorkey 'wizard'"),
        (["train", "--teachers", "optimal:1.5"], "probability 1.5 is outside [0, 1]"),
        (["train", "--steps", "0"], "expected a positive integer"),
        (["train", "--steps", "-5"], "expected a positive integer"),
        (["train", "--set", "gamma=2"], "gamma must be in [0, 1]"),
        (["eval", "/no/such/run"], "run folder '/no/such/run' does not exist"),
        (["train", "--algo", "ppo", "--teachers", "optimal"], "drop --teachers"),
        (["train", "--steps", "2.5e0"], "expected a positive integer, got '2.5e0'"),
        (["train", "--steps", "1e999"], "expected a positive integer, got '1e999'"),
        (["train", "--set", "learning_rate=.nan"], "learning_rate must be a finite number"),
        (["train", "--set", "target_kl=-1"], "target_kl must be > 0"),
        (["train", "--set", "normalize_advantage=maybe"], "must be true or false"),
        (
            ["train", "--algo", "ppo", "--set", "learning_rate=.nan"],
            "learning_rate must be a finite",
        ),
        (["train", "--algo", "dqn-tlql", "--set", "gamma=.inf"], "gamma must be a finite number"),
    ],
)
def test_bad_input_exits_2_with_one_line(args, fragment):
    proc = run_cli(*args)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    assert fragment in lines[0]
    assert "Traceback" not in proc.stderr


def _tree_bytes(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def test_out_refuses_a_finished_run_unless_forced(tmp_path):
    out = tmp_path / "run"
    base = ["train", "--steps", "64", "--out", str(out), "--no-progress", "--eval-episodes", "1"]
    assert main(base) == 0
    before = _tree_bytes(out)
    for extra in ([], ["--seed", "1"], ["--set", "learning_rate=.nan"]):
        proc = run_cli(*base, *extra)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
    assert _tree_bytes(out) == before  # nothing touched
    assert "finished run" in run_cli(*base).stderr
    assert main([*base, "--force", "--seed", "1"]) == 0
    assert "seed: 1" in (out / "config.yaml").read_text()
    # a folder holding something else is refused too, and left as it was
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    proc = run_cli("train", "--steps", "64", "--out", str(other), "--no-progress")
    assert proc.returncode == 2 and "is not empty" in proc.stderr
    assert _tree_bytes(other) == {"notes.txt": b"mine"}


def test_eval_of_a_folder_that_is_not_a_run(tmp_path):
    proc = run_cli("eval", str(tmp_path))
    assert proc.returncode == 2 and "config.yaml is missing" in proc.stderr


def test_envs_lists_doorkey():
    proc = run_cli("envs")
    assert proc.returncode == 0 and "doorkey" in proc.stdout and "optimal" in proc.stdout


def test_envs_and_train_say_how_to_use_a_gymnasium_id(capsys):
    assert main(["envs"]) == 0
    out = capsys.readouterr().out
    assert "Any registered Gymnasium id (CartPole-v1, ...) works from Python: " in out
    assert "as Gymnasium ids (gym.make): tlac/DoorKey-v0, tlac/DoorKeyPartial-v0" in out
    assert "TLAC('CartPole-v1', teachers=[...])" in out
    assert "tlac train --env CartPole-v1 --teachers path/to/file.py:NAME" in out
    assert "tlac train --env path/to/file.py:DOMAIN (examples/my_domain.py)" in out
    assert main(["train", "--env", "CartPole-v1", "--steps", "64"]) == 2
    err = capsys.readouterr().err
    assert "give --teachers path/to/file.py:NAME" in err and len(err.splitlines()) == 1


TINY = ["--set", "n_steps=64", "--set", "batch_size=64", "--eval-episodes", "2", "--no-progress"]


def test_train_a_gymnasium_id_with_teachers_from_files(tmp_path, capsys):
    from stable_baselines3 import PPO

    (tmp_path / "mine.py").write_text("def pd(obs):\n    return int(obs[2] + 0.5 * obs[3] > 0)\n")
    agent = tmp_path / "zoo" / "ppo.zip"
    PPO("MlpPolicy", "CartPole-v1", seed=0, device="cpu").save(agent)
    teachers = f"{tmp_path / 'mine.py'}:pd,{agent}:0.5,random"
    out = tmp_path / "run"
    argv = ["train", "--env", "CartPole-v1", "--teachers", teachers, "--steps", "128"]
    assert main([*argv, "--out", str(out), *TINY]) == 2  # an agent's pickles: not unasked
    err = capsys.readouterr().err
    assert "ppo.zip" in err and "pass --trust-pickle" in err and len(err.splitlines()) == 1
    assert not out.exists()
    assert main([*argv, "--out", str(out), *TINY, "--trust-pickle"]) == 0
    usage = (out / "teacher_usage.csv").read_text()
    assert ",pd," in usage and ",ppo:0.5," in usage and ",random," in usage
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env"] == "CartPole-v1" and config["teacher_kinds"] == teachers.split(",")
    capsys.readouterr()
    assert main(["eval", str(out), "--episodes", "2", "--json"]) == 0  # gym.make: no code
    assert json.loads(capsys.readouterr().out)["episodes"] == 2
    assert main(["eval", str(out), "--episodes", "2", "--with-teachers"]) == 2
    assert "pass --trust-code" in capsys.readouterr().err
    argv = ["eval", str(out), "--episodes", "2", "--with-teachers", "--json", "--trust-code"]
    assert main(argv) == 2
    assert "pass --trust-pickle" in capsys.readouterr().err
    assert main([*argv, "--trust-pickle"]) == 0
    assert "with_teachers_mean" in json.loads(capsys.readouterr().out)


def test_eval_imports_a_runs_domain_file_when_told_to(tmp_path, capsys):
    domain = Path(__file__).parents[1] / "examples" / "my_domain.py"
    out = tmp_path / "run"
    argv = ["train", "--env", f"{domain}:DOMAIN", "--steps", "64", "--out", str(out), *TINY]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["eval", str(out), "--episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert "domain file" in err and "pass --trust-code" in err and len(err.splitlines()) == 1
    assert main(["eval", str(out), "--episodes", "2", "--trust-code", "--with-teachers"]) == 0
    printed = capsys.readouterr().out
    assert "student alone (greedy, 2 episodes)" in printed and "with its teachers" in printed


def test_report_of_one_run_folder(tmp_path, capsys):
    out = tmp_path / "run"
    small = ["--set", "n_steps=32", "--set", "batch_size=32", "--log-interval", "32"]
    evals = ["--eval-every", "64", "--eval-episodes", "1", "--no-progress"]
    assert main(["train", "--steps", "128", *small, *evals, "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    assert f"wrote {out / 'report.md'}" in capsys.readouterr().out
    report = (out / "report.md").read_text()
    assert "Domain `doorkey`, 128 environment steps per run, seeds 0" in report
    assert "| optimal, random, random | `tlac` |" in report  # its teachers and algorithm
    assert (out / "figures" / "student_alone.png").exists()
    assert (out / "summary.csv").read_text().count("\n") == 2  # a header and the run
    assert main(["eval", str(out), "--episodes", "1"]) == 0  # still a run folder
    assert main(["report", str(tmp_path / "none")]) == 2
    assert "nor a run folder of tlac train (config.yaml)" in capsys.readouterr().err


def test_readme_starts_with_the_two_commands():
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text().splitlines()
    blocks = [line for line in readme[:40] if line.startswith("bash ") or line.startswith("python")]
    assert any("scripts/demo.sh" in b for b in blocks) and any(
        "scripts/test.sh" in b for b in blocks
    )


# keep_best True (a kill and resume with periodic evaluations, about 20 s) in the slow tier
@pytest.mark.parametrize("keep_best", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_an_interrupted_run_resumes_exactly(tmp_path, keep_best):
    """A TL-AC run stopped after a checkpoint and resumed with `tlac train --resume` ends with
    the same run files as an uninterrupted run (progress.csv without its wall-clock rows);
    with keep_best, the same deployed student (the best evaluation is part of the run state)."""
    import torch

    from tlac.run import RunSpec, resume_run, train_run

    spec = RunSpec(
        keep_best=keep_best,
        env="doorkey",
        teachers=["optimal", "random"],
        steps=3024,
        seed=2,
        eval_every=1008,
        eval_episodes=2,
        log_interval=504,
        # a linear schedule: the resumed part must continue it, not restart it
        overrides={"learning_rate": {"linear": [7.0e-4, 1.0e-4]}},
    )
    straight, broken = tmp_path / "straight", tmp_path / "broken"
    train_run(spec, straight, checkpoint_every=1008)

    class Crash(Exception):
        pass

    def crash_at_2016(timestep, student, train_return):
        if timestep >= 2016:
            raise Crash

    with pytest.raises(Crash):
        train_run(spec, broken, on_eval=crash_at_2016, checkpoint_every=1008)
    assert (broken / "checkpoint.pt").exists() and not (broken / "result.json").exists()
    proc = run_cli("train", "--resume", str(broken), "--no-progress", "--checkpoint-every", "1008")
    assert proc.returncode == 0, proc.stderr
    for name in ("episodes.csv", "eval.csv", "teacher_usage.csv"):
        assert (broken / name).read_bytes() == (straight / name).read_bytes(), name

    def without_clock(path):
        return [ln for ln in path.read_text().splitlines() if ",time/" not in ln]

    assert without_clock(broken / "progress.csv") == without_clock(straight / "progress.csv")
    assert not (broken / "checkpoint.pt").exists() and (broken / "result.json").exists()

    def outcome(folder):
        result = json.loads((folder / "result.json").read_text())
        return {k: v for k, v in result.items() if k not in ("wall_time_s", "steps_per_s")}

    assert outcome(broken) == outcome(straight)
    assert ("deployed_from_step" in outcome(straight)) == keep_best
    platform = outcome(straight)["platform"]  # where the run was made (docs/architecture.md)
    assert platform["torch"] == torch.__version__
    assert set(platform) >= {"python", "machine", "numpy"}
    with pytest.raises(TlacError, match="finished run"):
        resume_run(broken)


def test_a_run_folder_in_use_is_refused(tmp_path, capsys):
    from tlac.run import LOCK_FILE, folder_lock

    out = tmp_path / "run"
    out.mkdir()
    with folder_lock(out / LOCK_FILE, "held by this test"):
        code = main(["train", "--steps", "64", "--out", str(out), "--no-progress"])
    assert code == 2 and "is in use by another tlac process" in capsys.readouterr().err
    assert not (out / "config.yaml").exists()


def test_force_starts_afresh_and_a_rerun_continues(tmp_path, monkeypatch):
    """Without --force, `tlac train` on an unfinished run of the same settings continues from
    its checkpoint; with --force it starts again from step 0."""
    import tlac.run as run_module

    out = tmp_path / "run"
    args = ["train", "--steps", "1008", "--out", str(out), "--no-progress", "--eval-episodes", "1"]
    args += ["--checkpoint-every", "512", "--eval-every", "512"]
    seen: list[bool] = []
    real = run_module._train_locked

    def crash_after_a_checkpoint(*a, **kw):
        def crash(timestep, student, train_return):
            if timestep >= 1000:
                raise KeyboardInterrupt

        return real(*a, **{**kw, "on_eval": crash})

    monkeypatch.setattr(run_module, "_train_locked", crash_after_a_checkpoint)
    assert main(args) == 130  # interrupted after the checkpoint at 512 steps
    assert (out / "checkpoint.pt").exists()

    def spy(*a, **kw):
        seen.append(kw["meta"] is not None)  # continued from a checkpoint?
        return real(*a, **kw)

    monkeypatch.setattr(run_module, "_train_locked", spy)
    assert main([*args, "--force"]) == 0
    assert main(args) == 2  # now finished: refused
    shutil.rmtree(out)
    monkeypatch.setattr(run_module, "_train_locked", crash_after_a_checkpoint)
    assert main(args) == 130
    monkeypatch.setattr(run_module, "_train_locked", spy)
    assert main(args) == 0
    assert seen == [False, True]


KEEP_BEST_SPEC = dict(
    teachers=["optimal", "random"],
    steps=2048,
    seed=3,
    eval_every=512,
    eval_episodes=2,
    keep_best=True,
)
"""A keep_best run whose evaluations (steps 0, 512, 1024, 1536, 2048, on seed 10_003; the
deployed student's fresh one on seed 30_003) the tests script."""


def _script_evaluations(monkeypatch, scores: dict[int, list]) -> list[int]:
    """Replace tlac.run's evaluations by ``scores[seed]`` in turn (None: stop the run with
    KeyboardInterrupt); returns the list of the seeds asked for, in order."""
    import numpy as np

    import tlac.run as run_module

    left = {seed: iter(values) for seed, values in scores.items()}
    seeds: list[int] = []

    def scripted_evaluation(model, domain, episodes, seed, deterministic=True):
        seeds.append(seed)
        score = next(left[seed])
        if score is None:
            raise KeyboardInterrupt
        return np.full(episodes, score)

    monkeypatch.setattr(run_module, "evaluate_student", scripted_evaluation)
    return seeds


def test_keep_best_deploys_the_best_evaluation_and_scores_it_afresh(tmp_path, monkeypatch):
    """keep_best (tlac train's default with --eval-every): ``model`` is the student of the best
    periodic evaluation (the latest of equal ones), the last weights move to model-last, and
    final_eval_mean is the deployed student's return on fresh seeds (30_000 + seed), not the
    evaluation that chose it.
    The evaluations' scores are scripted, so that the choice is known."""
    from tlac import TLAC
    from tlac.run import RunSpec, train_run

    seeds = _script_evaluations(monkeypatch, {10_003: [0.1, 0.6, 0.2, 0.6, 0.3], 30_003: [0.5]})
    spec = RunSpec(**KEEP_BEST_SPEC)
    out = tmp_path / "run"
    result = train_run(spec, out)
    assert seeds == [10_003] * 5 + [30_003]
    assert result["deployed_from_step"] == 1536 and result["deployed_selection_mean"] == 0.6
    assert result["final_eval_mean"] == 0.5 and result["last_eval_mean"] == 0.3
    assert TLAC.load(out / "model").num_timesteps == 1536
    assert TLAC.load(out / "model-last").num_timesteps == 2048
    assert not (out / "model-best.pt").exists()
    # when the last evaluation is the best, the last weights are deployed
    _script_evaluations(monkeypatch, {10_003: [0.1, 0.6, 0.2, 0.6, 0.7], 30_003: [0.5]})
    result = train_run(spec, out)
    assert result["deployed_from_step"] == 2048 and not (out / "model-last.pt").exists()
    assert TLAC.load(out / "model").num_timesteps == 2048


def test_tlac_train_keeps_the_best_with_eval_every_unless_keep_last(tmp_path):
    base = ["train", "--steps", "64", "--no-progress", "--eval-episodes", "1"]
    for extra, kept in (
        ([], False),
        (["--eval-every", "32"], True),
        (["--eval-every", "32", "--keep-last"], False),
    ):
        out = tmp_path / f"run{len(extra)}"
        assert main([*base, *extra, "--out", str(out)]) == 0
        result = json.loads((out / "result.json").read_text())
        assert ("deployed_from_step" in result) == kept, extra
        assert yaml.safe_load((out / "config.yaml").read_text())["keep_best"] == kept


def test_a_run_stopped_while_deploying_the_best_continues(tmp_path, monkeypatch):
    """Stopped during the deployed student's fresh evaluation (after the last checkpoint, at
    the last step), the same command finishes the run with the same deployed model."""
    from tlac import TLAC
    from tlac.run import RunSpec, train_run

    _script_evaluations(monkeypatch, {10_003: [0.1, 0.6, 0.2, 0.6, 0.3], 30_003: [None, 0.5]})
    spec = RunSpec(**KEEP_BEST_SPEC)
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        train_run(spec, out, checkpoint_every=512)
    assert not (out / "result.json").exists() and (out / "checkpoint.pt").exists()
    result = train_run(spec, out, checkpoint_every=512, replace=False)
    assert result["deployed_from_step"] == 1536 and result["final_eval_mean"] == 0.5
    assert TLAC.load(out / "model").num_timesteps == 1536
    assert TLAC.load(out / "model-last").num_timesteps == 2048
    assert not (out / "checkpoint.pt").exists() and not (out / "model-best.pt").exists()
