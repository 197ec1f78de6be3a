"""Bad input, round two (issue 44): the cases of its battery that ended in a traceback, a raw
exception from the Python API, or nothing at all. Each ends in one line naming the culprit and
what is accepted: exit status 2 and one line on stderr from the CLI (run in-process, as in
tests/test_bad_input.py), a :class:`tlac.errors.TlacError` with the same message from the API.

The fault cases (a disk that fills up, a folder turned read-only while a run trains) run the
CLI in a subprocess and are marked ``slow``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from test_bad_input import one_line_error

from tlac.cli import main
from tlac.errors import ConfigError, StorageError, TeacherError, TlacError

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny-doorkey.yaml"
T = ["train", "--steps", "64", "--no-progress", "--eval-episodes", "1", "--log-interval", "32"]


def _grid_config() -> dict:
    grid = yaml.safe_load(TINY.read_text())
    grid.update(steps=64, seeds=1, eval={"every": 64, "episodes": 1}, log_interval=32)
    grid["teacher_sets"] = {"1optimal": {"teachers": ["optimal"]}}
    grid["algorithms"] = [{"name": "tlac"}]
    grid.pop("baseline", None)
    grid["metrics"].update(jumpstart_window=64, final_window=32)
    return grid


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A finished run and a finished tiny grid, made once."""
    root = tmp_path_factory.mktemp("round2")
    run = root / "run"
    assert main([*T, "--out", str(run)]) == 0
    config = root / "grid.yaml"
    config.write_text(yaml.safe_dump(_grid_config()))
    grid = root / "grid"
    assert main(["experiment", "run", str(config), "--out", str(grid)]) == 0
    return {"run": run, "grid": grid, "config": config}


# --------------------------------------------------------------------------- tlac train
def test_a_domain_file_with_a_syntax_error_names_the_file_and_line(tmp_path, capsys):
    domain = tmp_path / "broken_domain.py"
    domain.write_text("import math\ndef f(:\n    pass\n")
    line = one_line_error([*T, "--env", f"{domain}:DOMAIN", "--out", str(tmp_path / "o")], capsys)
    assert f"syntax error in {domain}, line 2" in line


def test_a_domain_file_that_raises_names_the_file_line_and_exception(tmp_path, capsys):
    domain = tmp_path / "raising_domain.py"
    domain.write_text("x = 1\nraise RuntimeError('no simulator here')\n")
    line = one_line_error([*T, "--env", f"{domain}:DOMAIN", "--out", str(tmp_path / "o")], capsys)
    assert f"raised RuntimeError in {domain}, line 2: no simulator here" in line


@pytest.mark.parametrize(("made_env", "shown"), [("42", "int 42"), ("'CartPole-v1'", "str")])
def test_a_domain_whose_make_env_makes_no_environment_is_one_line(
    made_env, shown, tmp_path, capsys
):
    domain = tmp_path / "not_an_env.py"
    domain.write_text(
        textwrap.dedent(f"""
        from tlac.domains import Domain
        from tlac.teachers.base import as_teacher

        DOMAIN = Domain(
            name="not-an-env", description="make_env makes no environment",
            make_env=lambda: {made_env}, teacher_names=("left",),
            make_teacher=lambda name, env, seed: as_teacher(lambda o: 0, env.action_space),
            default_teachers=("left",),
        )
        """)
    )
    line = one_line_error([*T, "--env", f"{domain}:DOMAIN", "--out", str(tmp_path / "o")], capsys)
    assert f"domain 'not-an-env': its make_env returned {shown}" in line
    assert "expected a gymnasium.Env, e.g. gym.make('CartPole-v1')" in line


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--set", "net_arch_low=[1000000000000, 64]"], "the networks (net_arch_high/low/critic"),
        (["--set", "n_steps=100000000"], "the rollout (n_steps=100000000 x 1 environments)"),
        (
            ["--set", "imitation_buffer_size=10000000000"],
            "the imitation buffer (imitation_buffer_size=10000000000)",
        ),
        (
            ["--algo", "dqn-tlql", "--set", "buffer_size=10000000000"],
            "the replay buffer (buffer_size=10000000000)",
        ),
        (
            ["--algo", "ac-teach", "--set", "buffer_size=10000000000"],
            "the replay buffer (buffer_size=10000000000)",
        ),
        (["--algo", "ppo", "--set", "n_steps=100000000"], "the rollout (n_steps=100000000"),
        (
            ["--algo", "ppo", "--set", "policy_kwargs={net_arch: [1000000000000]}"],
            "the networks (net_arch",
        ),
    ],
)
def test_a_size_beyond_the_memory_is_refused_before_allocation(args, fragment, tmp_path, capsys):
    out = tmp_path / "o"
    line = one_line_error([*T, *args, "--out", str(out)], capsys)
    assert fragment in line and "of memory, more than this machine has available" in line
    assert not out.exists()  # refused when the model was built: no half-made run folder


def test_the_memory_estimate_lets_the_presets_through():
    from tlac.memory import available_bytes, check_fits

    assert available_bytes() is None or available_bytes() > 0
    check_fits({"a DoorKey preset's buffers": 4 * 100_000 * 300}, "lower it")  # 120 MB


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--algo", "a2c", "--set", "n_steps=0"], "a2c setting n_steps must be a positive integer"),
        (["--algo", "ppo", "--set", "n_epochs=0"], "ppo setting n_epochs must be a positive"),
        (
            ["--algo", "a2c", "--set", "policy_kwargs={net_arch: [-5]}"],
            "policy_kwargs.net_arch: expected a list of positive layer sizes",
        ),
        (["--algo", "a2c", "--set", "policy_kwargs=5"], "policy_kwargs must be a mapping"),
        (["--out", ""], "--out '' names no folder"),
        (["--out", "x" * 300], "File name too long"),
    ],
)
def test_train_refuses(args, fragment, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    line = one_line_error([*T, *args], capsys)
    assert fragment in line
    assert not (tmp_path / "runs").exists()


def test_a2c_policy_kwargs_net_arch_is_used_not_replaced():
    from tlac.baselines.sb3_baselines import sb3_kwargs

    kwargs = sb3_kwargs("a2c", {"net_arch": [64, 64], "policy_kwargs": {"net_arch": [32]}})
    assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [32], "vf": [32]}


@pytest.mark.parametrize("content", [{"config.yaml": "mine: 1\n"}, {"notes.txt": "mine"}])
def test_force_refuses_a_folder_that_is_not_a_run(content, tmp_path, capsys):
    folder = tmp_path / "mine"
    folder.mkdir()
    for name, text in content.items():
        (folder / name).write_text(text)
    line = one_line_error([*T, "--out", str(folder), "--force"], capsys)
    assert "holds files that are not a run's; --force replaces a run folder only" in line
    for name, text in content.items():
        assert (folder / name).read_text() == text


def test_force_still_replaces_a_run(made, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    assert main([*T, "--out", str(run), "--force"]) == 0


@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("eval_every", "x", "eval_every must be a positive number of steps, got 'x'"),
        ("log_interval", "x", "log_interval must be a positive integer"),
        ("eval_episodes", "x", "eval_episodes must be an integer >= 0"),
        ("teacher_kinds", 5, "teachers must be a list of teacher names"),
        ("overrides", 7, "overrides must be a mapping"),
        ("overrides", {"wings": 3}, "unknown TL-AC setting 'wings'"),
    ],
)
def test_resume_names_a_bad_value_in_config_yaml(key, value, fragment, made, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    (run / "result.json").unlink()
    torch.save({"run": {"num_timesteps": 0}, "training": {}}, run / "checkpoint.pt")
    config = yaml.safe_load((run / "config.yaml").read_text())
    config[key] = value
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    line = one_line_error(["train", "--resume", str(run), "--no-progress"], capsys)
    assert f"{run / 'config.yaml'}': {fragment}" in line


@pytest.mark.parametrize("env", ["pickplace", "CartPole-v1"])
def test_resume_on_another_environment_than_the_checkpoints_is_one_line(
    env, made, tmp_path, capsys
):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    (run / "result.json").unlink()
    checkpoint = {"run": {"num_timesteps": 0}, "training": {}, "env_name": "doorkey"}
    torch.save(checkpoint, run / "checkpoint.pt")
    config = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**config, "env": env}))
    line = one_line_error(["train", "--resume", str(run), "--no-progress"], capsys)
    assert (
        f"{run / 'config.yaml'}': env is {env!r}, and the run's checkpoint was trained on "
        "'doorkey'; --resume continues a run on its own environment: put env: doorkey back"
    ) in line


# --------------------------------------------------------------------------- tlac eval
@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("algo", ["tlac", "ppo"], "algo must be a name, got ['tlac', 'ppo']"),
        ("env", {"name": "doorkey"}, "env must be a name, got {'name': 'doorkey'}"),
        ("seed", "zero", "seed must be an integer from 0 to 2147483647, got 'zero'"),
        ("seed", 1.5, "seed must be an integer from 0 to 2147483647, got 1.5"),
    ],
)
def test_eval_names_a_bad_value_in_config_yaml(key, value, fragment, made, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    config = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**config, key: value}))
    for args in (["--episodes", "1"], ["--episodes", "1", "--with-teachers"]):
        line = one_line_error(["eval", str(run), *args], capsys)
        assert f"{run / 'config.yaml'}': {fragment}" in line


def _damage_weights(state: dict, how: str) -> None:
    weight = next(k for k in state["net"] if k.startswith("weights"))
    if how == "missing key":
        del state["net"][weight]
    elif how == "wrong shape":
        state["net"][weight] = torch.zeros(3, 3)
    elif how == "broken optimizer":
        state["optimizer"] = {"state": {}, "param_groups": []}
    elif how == "NaN weights":
        state["net"][weight] = state["net"][weight] * float("nan")


DAMAGE = {
    "missing key": "is not a loadable TL-AC model file: RuntimeError",
    "wrong shape": "is not a loadable TL-AC model file: RuntimeError",
    "broken optimizer": "is not a loadable TL-AC model file: ValueError",
    "NaN weights": "the model's weights hold NaN or infinity (weights.",
}


@pytest.mark.parametrize("how", list(DAMAGE))
def test_eval_and_load_refuse_a_damaged_model(how, made, tmp_path, capsys):
    from tlac import TLAC

    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    state = torch.load(run / "model.pt", weights_only=True)
    _damage_weights(state, how)
    torch.save(state, run / "model.pt")
    line = one_line_error(["eval", str(run), "--episodes", "1"], capsys)
    assert f"'{run / 'model.pt'}'" in line and DAMAGE[how] in line
    with pytest.raises(ConfigError) as info:
        TLAC.load(run / "model.pt")
    assert DAMAGE[how] in str(info.value)


OTHER_ENV = "the model was trained on 'doorkey' and is used on 'doorkey-partial'"


def test_a_model_used_on_another_domain_is_one_warning_line(made, tmp_path, capsys):
    """A DoorKey model on doorkey-partial (the same observation shape) is said in one line by
    tlac eval and TLAC.load(env=...); a model file without the name (an older tlac) is not
    checked."""
    from tlac import TLAC

    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    assert torch.load(run / "model.pt", weights_only=True)["env_name"] == "doorkey"
    config = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**config, "env": "doorkey-partial"}))
    assert main(["eval", str(run), "--episodes", "1"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"tlac: warning: {OTHER_ENV}" in err
    with pytest.warns(UserWarning, match=OTHER_ENV):
        TLAC.load(run / "model.pt", env="doorkey-partial")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert TLAC.load(run / "model.pt", env="doorkey").env_name == "doorkey"
        state = torch.load(run / "model.pt", weights_only=True)
        del state["env_name"]  # as an older tlac saved it
        torch.save(state, run / "model.pt")
        assert TLAC.load(run / "model.pt", env="doorkey-partial").env_name == "doorkey-partial"
    assert not [w for w in caught if "trained on" in str(w.message)]
    assert main(["eval", str(run), "--episodes", "1"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_a_dqn_tlql_model_with_nan_weights_is_refused(tmp_path):
    from tlac.baselines.dqn_tlql import DQNTLQL
    from tlac.domains import get_domain, make_vec_env

    venv = make_vec_env(get_domain("doorkey"), 1, 0, None)
    model = DQNTLQL(venv, teachers=[], seed=0)
    path = model.save(tmp_path / "dqn")
    state = torch.load(path, weights_only=True)
    name = next(iter(state["state"]))
    key = next(k for k, v in state["state"][name].items() if v.is_floating_point())
    state["state"][name][key] = state["state"][name][key] * float("nan")
    torch.save(state, path)
    with pytest.raises(ConfigError, match="NaN or infinity"):
        DQNTLQL.load(path)


# --------------------------------------------------------------------------- tlac teacher
@pytest.mark.parametrize("value", ["nan", "inf", "-5"])
def test_teacher_train_time_limit_must_be_finite(value, capsys):
    line = one_line_error(
        ["teacher", "train", "hopper-bullet", "--steps", "10", "--time-limit", value], capsys
    )
    assert "--time-limit must be a finite number of seconds > 0" in line


@pytest.mark.parametrize("out", ["file/teachers", "file"])
def test_teacher_train_out_where_no_folder_can_be_is_one_line(out, tmp_path, capsys):
    (tmp_path / "file").write_text("a file, not a folder")
    args = ["teacher", "train", "doorkey", "--steps", "10", "--work-dir", str(tmp_path / "w")]
    line = one_line_error([*args, "--out", str(tmp_path / out)], capsys)
    assert (
        f"--out {str(tmp_path / out)!r} cannot be a folder: {str(tmp_path / 'file')!r} is a "
        "file; expected a folder path"
    ) in line
    assert not (tmp_path / "w").exists()  # refused before anything is written


# --------------------------------------------------------------------------- experiments
LAUGHS = "".join(
    f"{b}: &{b} [{', '.join([f'*{a}'] * 9)}]\n" for a, b in zip("abcdefgh", "bcdefghi", strict=True)
)


@pytest.mark.parametrize(
    ("edit", "fragment"),
    [
        (lambda text: text + "steps: 128\n", "key 'steps' is given twice (first on line"),
        (
            lambda text: 'a: &a ["lol", "lol"]\n' + LAUGHS + text,
            "its aliases expand to more than 1,000,000 values",
        ),
        (lambda text: "a: " + "[" * 50_000 + "]" * 50_000 + "\n" + text, "nested too deeply"),
        (lambda text: text.replace("seeds: 1\n", "seeds: 100000000\n"), "seeds from 1 to 10000"),
        (
            lambda text: text.replace("seeds: 1\n", "seeds: [0, 4294967296]\n"),
            "'seeds[1]': expected a seed from 0 to 2147483647",
        ),
    ],
)
@pytest.mark.parametrize("command", ["list", "run"])
def test_experiment_files_refuse(edit, fragment, command, made, tmp_path, capsys):
    config = tmp_path / "exp.yaml"
    config.write_text(edit(made["config"].read_text()))
    args = ["experiment", command, str(config)]
    if command == "run":
        args += ["--out", str(tmp_path / "grid")]
    line = one_line_error(args, capsys)
    assert fragment in line and "exp.yaml" in line


@pytest.mark.parametrize(
    ("teachers_json", "fragment"),
    [
        ("{{{ not json", "not readable JSON"),
        ("[1, 2]", "expected a JSON object of teacher name -> {mean, std, episodes}"),
        ('{"optimal": "x"}', "expected a JSON object of teacher name"),
        ('{"optimal": {"mean": "high"}}', "optimal.mean must be a number, got 'high'"),
    ],
)
def test_report_refuses_a_broken_teachers_json(teachers_json, fragment, made, tmp_path, capsys):
    grid = tmp_path / "grid"
    shutil.copytree(made["grid"], grid)
    (grid / "teachers.json").write_text(teachers_json)
    line = one_line_error(["report", str(grid)], capsys)
    assert "teachers.json" in line and fragment in line


def test_report_that_cannot_be_written_is_one_line(made, tmp_path, capsys):
    grid = tmp_path / "grid"
    shutil.copytree(made["grid"], grid)
    (grid / "report.md").mkdir()
    line = one_line_error(["report", str(grid)], capsys)
    assert f"cannot write the report into '{grid}'" in line and "Is a directory" in line


# --------------------------------------------------------------------------- the Python API
class _OldStepApi(gym.Env):
    observation_space = gym.spaces.Box(-1, 1, (3,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        return np.zeros(3, np.float32), {}

    def step(self, action):
        return np.zeros(3, np.float32), 0.0, False, {}  # gym < 0.26: four values


class _OldResetApi(_OldStepApi):
    def reset(self, seed=None, options=None):
        return np.zeros(3, np.float32)  # no info


class _WrongShape(_OldStepApi):
    def reset(self, seed=None, options=None):
        return np.zeros(5, np.float32), {}


@pytest.mark.parametrize(
    ("env_cls", "fragment"),
    [
        (_OldStepApi, "step() returned a 4-tuple; expected (observation, reward, terminated"),
        (_OldResetApi, "reset() returned ndarray; expected (observation, info)"),
        (_WrongShape, "reset() returned an observation of shape (5,); its observation_space is"),
    ],
)
def test_an_environment_off_gymnasiums_api_is_one_error(env_cls, fragment):
    from tlac import TLAC

    model = TLAC(env_cls(), seed=0, n_steps=16, batch_size=16)
    with pytest.raises(ConfigError) as info:
        model.learn(16, progress_bar=False)
    assert fragment in str(info.value)


PAST_AUDITION = {"CartPole-v1": 400, "Pendulum-v1": 1100}
"""Steps after which a default TL-AC run has asked its teacher: the first 5 episodes are the
student's alone (SoloEpisodes.auditioning; CartPole's untrained ones last ~20 steps,
Pendulum's 200), then the teacher leads one."""


@pytest.mark.parametrize(
    ("action", "fragment"),
    [
        (1e30, "returned action 1e+30 outside Discrete(2)"),
        (1 + 0j, "returned (1+0j)"),
        (np.array(object(), dtype=object), "dtype=object"),
        ("left", "returned 'left'"),
    ],
)
def test_a_teacher_returning_garbage_is_one_error(action, fragment):
    from tlac import TLAC

    model = TLAC(
        gym.make("CartPole-v1"), teachers=[lambda obs: action], seed=0, n_steps=16, batch_size=16
    )
    with pytest.raises(TeacherError) as info:
        model.learn(PAST_AUDITION["CartPole-v1"], progress_bar=False)
    assert fragment in str(info.value)


class _Batched:
    """A batched teacher returning ``make(n)`` for a batch of ``n`` observations."""

    def __init__(self, make):
        self.make, self.name = make, "batched"

    def predict(self, obs):
        return self.make(len(obs))


@pytest.mark.parametrize("env_id", ["CartPole-v1", "Pendulum-v1"])
@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda n: np.array(["left"] * n), "returned actions of dtype <U4 ('left')"),
        (lambda n: ["a"] * n, "returned actions of dtype <U1 ('a')"),
        (lambda n: np.ones(n, complex), "returned actions of dtype complex128 ((1+0j))"),
        (lambda n: np.array([object()] * n), "returned actions of dtype object (<object"),
    ],
)
def test_a_batched_teacher_returning_no_numbers_is_one_error(env_id, make, fragment):
    from tlac import TLAC

    env = gym.make(env_id)
    box = isinstance(env.action_space, gym.spaces.Box)
    shaped = (lambda n: np.asarray(make(n)).reshape(n, 1)) if box else make
    model = TLAC(env, teachers=[_Batched(shaped)], seed=0, n_steps=16, batch_size=16)
    with pytest.raises(TeacherError) as info:
        model.learn(PAST_AUDITION[env_id], progress_bar=False)
    assert f"teacher 'batched' {fragment}" in str(info.value)
    assert f"expected numbers, actions of {env.action_space}" in str(info.value)


@pytest.mark.parametrize("path", ["", 3, None, "   "])
def test_save_to_a_non_path_is_one_error(path):
    from tlac import TLAC

    with pytest.raises(ConfigError, match="expected a file path"):
        TLAC("doorkey", teachers=["optimal"], n_steps=16, batch_size=16).save(path)


def test_save_where_nothing_can_be_written_is_one_error():
    from tlac import TLAC

    with pytest.raises(StorageError, match="cannot write '/proc/"):
        TLAC("doorkey", teachers=["optimal"], n_steps=16, batch_size=16).save("/proc/m.pt")


def test_teachers_as_one_string_say_a_list_is_expected():
    from tlac import TLAC

    with pytest.raises(TlacError, match="teachers must be a list"):
        TLAC("doorkey", teachers="optimal")


# --------------------------------------------------------------------------- faults mid-run
FAULT_SCRIPT = """
import os, resource, signal, stat, sys
import tlac.run
from tlac.cli import main

fault = sys.argv[1]
evaluate = tlac.run.evaluate_student

def evaluate_then_fail(model, *args, **kwargs):
    returns = evaluate(model, *args, **kwargs)
    if model.num_timesteps >= 1024:  # after the checkpoints at 512 and 1024: the next write fails
        if fault == "disk full":
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (1000, resource.RLIM_INFINITY))
        elif os.geteuid() == 0:  # root writes anywhere: become nobody, who may not write here
            os.setuid(65534)
        else:
            os.chmod(sys.argv[2], stat.S_IRUSR | stat.S_IXUSR)
    return returns

tlac.run.evaluate_student = evaluate_then_fail
sys.exit(main(sys.argv[3:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["disk full", "read-only"])
def test_a_fault_mid_run_is_one_line_and_resume_finishes(fault, tmp_path):
    base = Path(tempfile.mkdtemp(prefix="tlac-fault-"))  # not under pytest's 0700 folders:
    base.chmod(0o755)  # the read-only case as root runs on as nobody, who must reach the run
    try:
        _fault_then_resume(fault, base / "run", tmp_path)
    finally:
        shutil.rmtree(base, ignore_errors=True)


def _fault_then_resume(fault: str, run: Path, tmp_path: Path) -> None:
    script = tmp_path / "fault.py"
    script.write_text(textwrap.dedent(FAULT_SCRIPT))
    args = [
        *["train", "--steps", "3072", "--no-progress", "--out", str(run)],
        *["--checkpoint-every", "512", "--eval-every", "1024", "--eval-episodes", "1"],
        *["--set", "n_steps=128", "--set", "batch_size=64", "--set", "imitation_buffer_size=256"],
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(script), fault, str(run), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode == 2, done.stderr
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    reason = "File too large" if fault == "disk full" else "Permission denied"
    assert lines[0].startswith("tlac: error: cannot write") and reason in lines[0], lines[0]
    assert f"tlac train --resume {run} continues from its last checkpoint" in lines[0]
    os.chmod(run, 0o755)
    assert not (run / "result.json").exists()
    resumed = subprocess.run(
        [sys.executable, "-m", "tlac", "train", "--resume", str(run), "--no-progress"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert resumed.returncode == 0, resumed.stderr
    assert (run / "result.json").exists()


def test_eval_of_a_garbage_sb3_zip_with_trust_pickle_is_one_line(made, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    (run / "model.pt").unlink()
    (run / "model.zip").write_bytes(b"not a zip file" * 40)
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["algo"] = "ppo"
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    line = one_line_error(["eval", str(run), "--episodes", "1", "--trust-pickle"], capsys)
    assert f"'{run / 'model.zip'}' is not a loadable ppo model (SB3 zip)" in line


def test_resume_sends_a_run_with_a_person_as_a_teacher_to_tlac_teach(made, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(made["run"], run)
    (run / "result.json").unlink()
    torch.save({"run": {"num_timesteps": 0}, "training": {}}, run / "checkpoint.pt")
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["teacher_kinds"] = ["human", "random"]
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    line = one_line_error(["train", "--resume", str(run), "--no-progress"], capsys)
    assert "has a person as a teacher: continue it with the tlac teach command" in line
