"""Files tlac reads on its own run no code, and a resumed run ends as if never stopped (issue 44,
points 1 and 3).

- A checkpoint is read with ``torch.load(weights_only=True)`` and holds no pickle: a crafted
  one is refused, and the pickled environments of an older checkpoint are never unpickled.
- A stable-baselines3 ``.zip`` (whose pickles run code) is opened only with an explicit
  ``trust_pickle=True`` / ``--trust-pickle``; the crafted zip below does run its code when
  trusted, so each refusal is a real protection.
- A run stopped after a checkpoint and resumed ends with every file byte-identical to the
  uninterrupted run's, model.pt included, wall-clock fields aside; a torn last row is cut.
"""

from __future__ import annotations

import base64
import json
import pickle
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from tlac import TLAC
from tlac.cli import main
from tlac.errors import ConfigError
from tlac.run import RunSpec, _keep_rows_until, resume_run, train_run

ROOT = Path(__file__).resolve().parents[1]


class RunsCode:
    """Unpickling this creates ``marker``: proof that a file ran code when it was read."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def sb3_zip(path: Path, marker: Path) -> Path:
    """A stable-baselines3 model zip whose ``policy_class`` is a pickle that creates
    ``marker`` (SB3 unpickles such entries with cloudpickle when it loads the file)."""
    payload = base64.b64encode(pickle.dumps(RunsCode(marker))).decode()
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("data", json.dumps({"policy_class": {":serialized:": payload}}))
    return path


def test_a_crafted_checkpoint_is_refused_without_running_code(tmp_path: Path, capsys) -> None:
    marker = tmp_path / "code-ran"
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text(yaml.safe_dump({"env": "doorkey", "algo": "tlac"}))
    torch.save(
        {"format": "tlac.TLAC/2", "run": {}, "training": RunsCode(marker)}, run / "checkpoint.pt"
    )
    with pytest.raises(ConfigError, match="not a loadable checkpoint file"):
        resume_run(run)
    assert main(["train", "--resume", str(run), "--no-progress"]) == 2
    assert "checkpoint.pt" in capsys.readouterr().err
    assert not marker.exists()


def test_an_older_checkpoints_pickled_environments_are_never_unpickled(tmp_path: Path) -> None:
    """Checkpoints of an older tlac held the environments as a pickle in a byte tensor, which a
    resume unpickled. That pickle is ignored now: the resume starts new episodes, with a
    warning that says why, and the code in it does not run."""
    marker = tmp_path / "code-ran"
    model = TLAC("doorkey", teachers=["random"], seed=0, n_envs=1, n_steps=32, batch_size=32)
    model.learn(64)
    path = model.save(tmp_path / "ck", training_state=True)
    state = torch.load(path, weights_only=True)
    env_state = state["training"]["env"]
    del env_state["episodes"]
    blob = pickle.dumps(RunsCode(marker))
    env_state["envs"] = torch.frombuffer(bytearray(blob), dtype=torch.uint8)
    torch.save(state, path)
    with pytest.warns(UserWarning, match="older tlac, which pickled its environments"):
        resumed = TLAC.load(path, env="doorkey", teachers=["random"], resume=True)
    resumed.learn(32, reset_num_timesteps=False)
    assert resumed.num_timesteps == 96 and not marker.exists()


def test_an_sb3_zip_is_opened_only_when_trusted(tmp_path: Path) -> None:
    from tlac.baselines.sb3_baselines import PPOBaseline
    from tlac.teachers import from_rl_zoo, from_sb3

    marker = tmp_path / "code-ran"
    crafted = sb3_zip(tmp_path / "model.zip", marker)
    zoo = tmp_path / "ppo" / "CartPole-v1_1"
    zoo.mkdir(parents=True)
    sb3_zip(zoo / "CartPole-v1.zip", marker)
    for load in (
        lambda: from_sb3(crafted, algo="ppo"),
        lambda: from_rl_zoo(zoo),
        lambda: PPOBaseline.load(tmp_path / "model"),
    ):
        with pytest.raises(ConfigError, match=r"can run any code.*trust_pickle=True"):
            load()
    assert not marker.exists()
    with pytest.raises(Exception):  # noqa: B017 - trusted, SB3 unpickles it: the code runs
        PPOBaseline.load(tmp_path / "model", trust_pickle=True)
    assert marker.exists()


def test_the_cli_opens_an_sb3_zip_only_with_trust_pickle(tmp_path: Path, capsys) -> None:
    marker = tmp_path / "code-ran"
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text(yaml.safe_dump({"env": "doorkey", "algo": "ppo", "seed": 0}))
    sb3_zip(run / "model.zip", marker)
    assert main(["eval", str(run), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "model.zip" in err and "--trust-pickle" in err and len(err.strip().splitlines()) == 1
    work = tmp_path / "work"
    work.mkdir()
    sb3_zip(work / "checkpoint.zip", marker)
    argv = ["teacher", "train", "doorkey", "--steps", "10", "--work-dir", str(work)]
    assert main([*argv, "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert "--trust-pickle" in capsys.readouterr().err
    assert not marker.exists()


def test_tlac_eval_imports_no_domain_file(tmp_path: Path, capsys) -> None:
    marker = tmp_path / "code-ran"
    domain = tmp_path / "my_domain.py"
    domain.write_text(f"open({str(marker)!r}, 'w')\n")
    run = tmp_path / "run"
    run.mkdir()
    config = {"env": f"{domain}:DOMAIN", "algo": "tlac", "seed": 0}
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    (run / "model.pt").write_bytes(b"")
    assert main(["eval", str(run), "--episodes", "1"]) == 2
    assert "pass --trust-code if you trust the file" in capsys.readouterr().err
    assert not marker.exists()


def test_an_sb3_zip_teacher_is_opened_only_with_trust_pickle(tmp_path: Path, capsys) -> None:
    marker = tmp_path / "code-ran"
    agent = sb3_zip(tmp_path / "agent.zip", marker)
    out = tmp_path / "out"
    argv = ["train", "--env", "CartPole-v1", "--teachers", f"{agent}:0.5", "--out", str(out)]
    assert main([*argv, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "agent.zip" in err and "--trust-pickle" in err and len(err.strip().splitlines()) == 1
    assert not marker.exists() and not out.exists()


def test_a_torn_last_row_is_cut_and_a_garbage_row_named(tmp_path: Path) -> None:
    csv = tmp_path / "episodes.csv"
    csv.write_bytes(b"timestep,return,length\r\n100,0.5,100\r\n250,0.9,150\r\n3")
    _keep_rows_until(csv, 300)  # "3" is what was written of the row at step 3xx
    assert csv.read_bytes() == b"timestep,return,length\r\n100,0.5,100\r\n250,0.9,150\r\n"
    _keep_rows_until(csv, 200)
    assert csv.read_bytes() == b"timestep,return,length\r\n100,0.5,100\r\n"
    csv.write_bytes(b"timestep,return,length\n100,0.5,100\nnot a row\n")
    with pytest.raises(ConfigError, match=r"episodes.csv' line 3 is not a row of this run"):
        _keep_rows_until(csv, 200)


def assert_same_run_files(folder: Path, reference: Path) -> None:
    """Every file byte-identical, model.pt included, except the wall-clock fields listed in
    docs/architecture.md."""
    names = sorted(p.name for p in reference.iterdir() if p.is_file())
    assert names == sorted(p.name for p in folder.iterdir() if p.is_file())
    for name in names:
        got, want = (folder / name).read_bytes(), (reference / name).read_bytes()
        if name == "progress.csv":
            got, want = ([ln for ln in t.splitlines() if b",time/" not in ln] for t in (got, want))
        elif name == "monitor.csv":
            got, want = ([ln.rsplit(b",", 1)[0] for ln in t.splitlines()[1:]] for t in (got, want))
        elif name == "result.json":
            wall = ("wall_time_s", "steps_per_s")
            got, want = (
                {k: v for k, v in json.loads(t).items() if k not in wall} for t in (got, want)
            )
        assert got == want, name


SPEC = RunSpec(
    env="doorkey",
    teachers=["optimal", "random"],
    steps=1200,
    seed=3,
    eval_every=500,
    eval_episodes=1,
    log_interval=600,  # the checkpoint at 900 falls inside a logging window
    overrides={"n_steps": 100, "batch_size": 100},
)


def test_a_resumed_run_ends_byte_identical_torn_rows_and_all(tmp_path: Path) -> None:
    """Stopped at step 1000 (checkpoint at 900, inside the logging window 600-1200), torn
    rows left at the end of its CSVs as a kill while writing leaves them, resumed: every file
    as the uninterrupted run's, progress.csv's train/* means and model.pt's bytes included."""
    straight, broken = tmp_path / "straight", tmp_path / "broken"
    train_run(SPEC, straight, checkpoint_every=300)

    class Crash(Exception):
        pass

    def crash(timestep: int, student: float, train_return: float | None) -> None:
        if timestep >= 1000:
            raise Crash

    with pytest.raises(Crash):
        train_run(SPEC, broken, on_eval=crash, checkpoint_every=300)
    for name in ("episodes.csv", "progress.csv", "teacher_usage.csv", "eval.csv"):
        with (broken / name).open("ab") as f:
            f.write(b"1")  # a row of a step after the checkpoint, torn after its first digit
    resume_run(broken, checkpoint_every=300)
    assert_same_run_files(broken, straight)


@pytest.mark.slow
def test_kill_9_and_resume_end_byte_identical(tmp_path: Path) -> None:
    """The soak benchmark in small: `tlac train` killed with SIGKILL twice at random points,
    continued once with --resume and once with the same command, against the run left alone."""
    script = ROOT / "benchmarks" / "soak_resume.py"
    args = ["--steps", "3000", "--checkpoint-every", "500", "--kills", "2"]
    proc = subprocess.run(
        [sys.executable, str(script), *args, "--work", str(tmp_path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "byte-identical except the wall-clock fields" in proc.stdout


def test_episodes_are_re_created_not_unpickled() -> None:
    """The checkpoint's environment state is plain data: a seed or a generator state, the
    actions as a tensor and a digest; replayed in a fresh copy it gives the same episode."""
    from tlac.domains import get_domain, make_vec_env

    venv = make_vec_env(get_domain("doorkey"), 2, 0, None)
    venv.reset()
    for _ in range(40):
        venv.step(np.array([2, 1]))
    env = venv.venv.envs[0]
    state = env.state()
    assert set(state) == {"seed", "rng", "actions", "steps", "obs_sha256"}
    assert isinstance(state["actions"], torch.Tensor)
    fresh = make_vec_env(get_domain("doorkey"), 2, 0, None).venv.envs[0]
    assert fresh.replay(state)
    assert fresh.unwrapped.agent_pos == env.unwrapped.agent_pos
    state["obs_sha256"] = "0" * 64  # another episode: refused, not trusted
    assert not make_vec_env(get_domain("doorkey"), 2, 0, None).venv.envs[0].replay(state)
