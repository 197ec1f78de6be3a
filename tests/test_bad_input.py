"""Bad input, tried as a new user would (issue 10): every case gets ONE clear error.

CLI cases: exit status 2, exactly one line on stderr that names the culprit, no traceback.
API cases: a :class:`tlac.errors.TlacError` whose message names the culprit.
Every case also checks that a finished run and a finished grid made before it are
byte-identical afterwards: bad input never destroys data.

The commands run in-process (``tlac.cli.main``) in a scratch working directory, so that a case
that would fall back to the default ``runs/...`` folder cannot touch the repository.
"""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml

from tlac.cli import main
from tlac.errors import TlacError

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny-doorkey.yaml"


def _tree(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.name.endswith(".lock")
    }


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A finished run, a finished tiny grid, and broken copies of both to feed the commands."""
    root = tmp_path_factory.mktemp("made")
    run = root / "run"
    common = ["--no-progress", "--eval-episodes", "1", "--log-interval", "32"]
    assert main(["train", "--steps", "64", "--out", str(run), *common]) == 0
    grid_cfg = yaml.safe_load(TINY.read_text())
    grid_cfg.update(steps=64, seeds=1, eval={"every": 64, "episodes": 1}, log_interval=32)
    grid_cfg["teacher_sets"] = {"1optimal": {"teachers": ["optimal"]}}
    grid_cfg["algorithms"] = [{"name": "tlac"}]
    grid_cfg.pop("baseline", None)
    grid_cfg["metrics"].update(jumpstart_window=64, final_window=32)
    config = root / "grid.yaml"
    config.write_text(yaml.safe_dump(grid_cfg))
    grid = root / "grid"
    assert main(["experiment", "run", str(config), "--out", str(grid)]) == 0
    broken = root / "broken"
    broken.mkdir()
    files = {
        "garbage.yaml": "{{{ not yaml",
        "list.yaml": "- just\n- a list\n",
        "empty.yaml": "",
        "no_domain.yaml": yaml.safe_dump({k: v for k, v in grid_cfg.items() if k != "domain"}),
        "bad_domain.yaml": yaml.safe_dump({**grid_cfg, "domain": "atari"}),
        "bad_steps.yaml": yaml.safe_dump({**grid_cfg, "steps": -3}),
        "nan_steps.yaml": yaml.safe_dump({**grid_cfg, "steps": float("nan")}),
        "bad_seeds.yaml": yaml.safe_dump({**grid_cfg, "seeds": "many"}),
        "zero_seeds.yaml": yaml.safe_dump({**grid_cfg, "seeds": 0}),
        "unknown_key.yaml": yaml.safe_dump({**grid_cfg, "stepz": 5}),
        "bad_algo.yaml": yaml.safe_dump({**grid_cfg, "algorithms": [{"name": "sac"}]}),
        "no_algos.yaml": yaml.safe_dump({**grid_cfg, "algorithms": []}),
        "bad_teacher.yaml": yaml.safe_dump(
            {**grid_cfg, "teacher_sets": {"x": {"teachers": ["wizard"]}}}
        ),
        "nan_override.yaml": yaml.safe_dump(
            {**grid_cfg, "algorithms": [{"name": "tlac", "overrides": {"learning_rate": "nan"}}]}
        ),
        "neg_override.yaml": yaml.safe_dump(
            {**grid_cfg, "algorithms": [{"name": "tlac", "overrides": {"clip_range": -1}}]}
        ),
        "unknown_override.yaml": yaml.safe_dump(
            {**grid_cfg, "algorithms": [{"name": "tlac", "overrides": {"wings": 2}}]}
        ),
    }
    for name, text in files.items():
        (broken / name).write_text(text)
    # run folders with one file broken each
    for name, damage in {
        "bad_config_run": ("config.yaml", b"{{{ not yaml"),
        "empty_config_run": ("config.yaml", b""),
        "empty_model_run": ("model.pt", b""),
        "garbage_model_run": ("model.pt", b"garbage" * 100),
        "truncated_model_run": ("model.pt", None),
        "no_model_run": ("model.pt", "delete"),
        "bad_algo_run": ("config.yaml", "algo"),
    }.items():
        target = broken / name
        shutil.copytree(run, target)
        file, data = damage
        if data is None:
            raw = (target / file).read_bytes()
            (target / file).write_bytes(raw[: len(raw) // 3])
        elif data == "delete":
            (target / file).unlink()
        elif data == "algo":
            cfg = yaml.safe_load((target / file).read_text())
            cfg["algo"] = "sac"
            (target / file).write_text(yaml.safe_dump(cfg))
        else:
            (target / file).write_bytes(data)
    # experiment folders with one file broken each
    for name, (file, data) in {
        "bad_experiment_yaml": ("experiment.yaml", b"{{{"),
        "no_experiment_yaml": ("experiment.yaml", None),
        "bad_episodes_csv": ("runs/*/episodes.csv", b"not,a\ncsv,,,\x00"),
    }.items():
        target = broken / name
        shutil.copytree(grid, target)
        for path in target.glob(file):
            if data is None:
                path.unlink()
            else:
                path.write_bytes(data)
    (broken / "a_file").write_text("I am a file")
    sb3_zip = broken / "sb3.zip"
    with zipfile.ZipFile(sb3_zip, "w") as z:
        z.writestr("data", "{}")
    return {"run": run, "grid": grid, "broken": broken, "root": root}


@pytest.fixture
def scratch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, made: dict[str, Path]) -> Path:
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _placeholders(args: list[str], made: dict[str, Path]) -> list[str]:
    return [
        a.replace("NEW", "new-grid")
        .replace("RUN", str(made["run"]))
        .replace("GRID", str(made["grid"]))
        .replace("BROKEN", str(made["broken"]))
        for a in args
    ]


T = ["train", "--steps", "64", "--no-progress"]  # a valid base for the train cases

CLI_CASES: list[tuple[list[str], str]] = [
    # --env / --algo / --selector / --preset
    ([*T, "--env", "atari"], "unknown environment 'atari'"),
    ([*T, "--env", ""], "unknown environment ''"),
    ([*T, "--env", "DoorKey-v0"], "unknown environment"),
    ([*T, "--algo", "sac"], "invalid choice: 'sac'"),
    ([*T, "--algo", ""], "invalid choice"),
    ([*T, "--selector", "greedy"], "invalid choice: 'greedy'"),
    ([*T, "--preset", "nowhere"], "nowhere"),
    ([*T, "--env", "doorkey", "--algo", "ppo", "--teachers", "optimal"], "drop --teachers"),
    # --teachers
    ([*T, "--teachers", "wizard"], "unknown teacher for doorkey 'wizard'"),
    ([*T, "--teachers", "optimal,wizard"], "'wizard'"),
    ([*T, "--teachers", ",,"], "--teachers"),
    ([*T, "--teachers", ""], "--teachers"),
    ([*T, "--teachers", " , "], "--teachers"),
    ([*T, "--teachers", "optimal:1.5"], "probability 1.5 is outside [0, 1]"),
    ([*T, "--teachers", "optimal:-0.1"], "outside [0, 1]"),
    ([*T, "--teachers", "optimal:abc"], "'abc'"),
    ([*T, "--teachers", "optimal:nan"], "optimal:nan"),
    ([*T, "--teachers", "optimal:"], "optimal:"),
    ([*T, "--teachers", "Optimal"], "'Optimal'"),
    # --steps
    (["train", "--steps", "0"], "expected a positive integer, got '0'"),
    (["train", "--steps", "-5"], "got '-5'"),
    (["train", "--steps", "2.5"], "got '2.5'"),
    (["train", "--steps", "2.5e0"], "got '2.5e0'"),
    (["train", "--steps", "1e999"], "got '1e999'"),
    (["train", "--steps", "abc"], "got 'abc'"),
    (["train", "--steps", ""], "got ''"),
    (["train", "--steps", "nan"], "got 'nan'"),
    (["train", "--steps", "inf"], "got 'inf'"),
    (["train", "--steps", "1e-3"], "got '1e-3'"),
    # --seed
    ([*T, "--seed", "-1"], "expected a non-negative integer, got '-1'"),
    ([*T, "--seed", "4294967296"], "seed must be an integer from 0 to 2147483647"),
    ([*T, "--algo", "dqn-tlql", "--selector", "ucb1"], "--selector ucb1 replaces TL-AC's"),
    ([*T, "--set", "preset=hopper"], "the preset is chosen with --preset"),
    ([*T, "--set", "schedule_horizon=10"], "schedule_horizon: expected an integer >= the run's"),
    ([*T, "--set", "schedule_horizon=1e6"], "schedule_horizon: expected an integer"),
    ([*T, "--algo", "ac-teach", "--set", "gamma=1.5"], "gamma"),
    ([*T, "--seed", "1.5"], "got '1.5'"),
    ([*T, "--seed", "abc"], "got 'abc'"),
    ([*T, "--seed", "nan"], "got 'nan'"),
    ([*T, "--seed", ""], "got ''"),
    # --eval-every / --eval-episodes / --log-interval
    ([*T, "--eval-every", "0"], "--eval-every"),
    ([*T, "--eval-every", "-100"], "--eval-every"),
    ([*T, "--eval-every", "abc"], "--eval-every"),
    ([*T, "--eval-episodes", "-1"], "--eval-episodes"),
    ([*T, "--eval-episodes", "x"], "--eval-episodes"),
    ([*T, "--log-interval", "0"], "--log-interval"),
    ([*T, "--log-interval", "-1"], "--log-interval"),
    # --set: form and names
    ([*T, "--set", "learning_rate"], "--set expects KEY=VALUE"),
    ([*T, "--set", "=3"], "''"),
    ([*T, "--set", "wings=2"], "unknown TL-AC setting 'wings'"),
    ([*T, "--set", "x=[1"], "not a YAML value"),
    ([*T, "--algo", "ppo", "--set", "wings=2"], "unknown ppo hyperparameter 'wings'"),
    ([*T, "--algo", "dqn-tlql", "--set", "wings=2"], "unknown dqn-tlql hyperparameter"),
    ([*T, "--algo", "ac-teach", "--set", "wings=2"], "unknown ac-teach hyperparameter"),
    ([*T, "--algo", "a2c", "--set", "wings=2"], "unknown a2c hyperparameter"),
]

# --set values: every numeric TL-AC setting with NaN, infinity, text and a wrong sign
for key in ("learning_rate", "gamma", "gae_lambda", "vf_coef", "max_grad_norm", "ent_coef"):
    for value, fragment in ((".nan", "finite"), (".inf", "finite"), ("abc", "number")):
        CLI_CASES.append(([*T, "--set", f"{key}={value}"], f"{key} must be a {fragment}"))
for key in ("learning_rate", "clip_range", "target_kl", "optimizer_eps"):
    CLI_CASES.append(([*T, "--set", f"{key}=-1"], f"{key} must be > 0"))
    CLI_CASES.append(([*T, "--set", f"{key}=0"], f"{key} must be > 0"))
for key in ("vf_coef", "max_grad_norm", "ent_coef", "solo_budget", "ent_cap_high"):
    CLI_CASES.append(([*T, "--set", f"{key}=-0.5"], f"{key} must be >= 0"))
for key in ("gamma", "gae_lambda", "teacher_episodes"):
    CLI_CASES.append(([*T, "--set", f"{key}=1.5"], f"{key} must be in [0, 1]"))
for key in ("n_steps", "batch_size", "n_epochs", "imitation_batch_size", "imitation_buffer_size"):
    for value in ("0", "-3", "2.5", "abc", "true"):
        CLI_CASES.append(([*T, "--set", f"{key}={value}"], key))
for key in (
    "normalize_advantage",
    "use_sde",
    "wean_imitation",
):
    for value in ("maybe", "1", "yes_please"):
        CLI_CASES.append(([*T, "--set", f"{key}={value}"], f"{key} must be true or false"))
for value in ("maybe", "1", "yes_please"):  # a switch with an "auto" mode
    CLI_CASES.append(([*T, "--set", f"normalize_obs={value}"], "normalize_obs must be"))
for key, value in (
    ("variant", "exact"),
    ("optimizer", "sgd"),
    ("kl_rows", "some"),
    ("obs_encoding", "jpeg"),
    ("low_level_data", "some"),
    ("update_rule", "together"),
):
    CLI_CASES.append(([*T, "--set", f"{key}={value}"], f"'{value}'"))
CLI_CASES.append(([*T, "--set", "selector=oracle"], "chosen with --selector"))
CLI_CASES.append(([*T, "--set", "advice_labels=sampled"], "unknown TL-AC setting 'advice_labels'"))
CLI_CASES += [
    ([*T, "--set", "learning_rate={linear: [1.0e-3, .nan]}"], "learning_rate must be"),
    ([*T, "--set", "learning_rate={linear: [1.0e-3]}"], "learning_rate"),
    ([*T, "--set", "learning_rate={cosine: [1, 2]}"], "learning_rate"),
    ([*T, "--set", "net_arch_low=[64, -1]"], "net_arch_low"),
    ([*T, "--set", "net_arch_low=[64]"], "same, non-zero number of layers"),
    ([*T, "--set", "batch_size=999"], "batch_size 999 exceeds the rollout size"),
    ([*T, "--algo", "ppo", "--set", "learning_rate=.nan"], "learning_rate must be a finite"),
    ([*T, "--algo", "ppo", "--set", "learning_rate=-1"], "learning_rate must be > 0"),
    ([*T, "--algo", "ppo", "--set", "normalize_advantage=maybe"], "true or false"),
    ([*T, "--algo", "a2c", "--set", "gamma=.inf"], "gamma must be a finite"),
    ([*T, "--algo", "dqn-tlql", "--set", "gamma=.inf"], "gamma must be a finite number"),
    ([*T, "--algo", "dqn-tlql", "--set", "learning_rate=0"], "learning_rate must be > 0"),
    ([*T, "--algo", "dqn-tlql", "--set", "batch_size=0"], "batch_size"),
    ([*T, "--algo", "ac-teach", "--set", "critic_lr=.nan"], "critic_lr must be a finite"),
    ([*T, "--algo", "ac-teach", "--set", "mc_samples=0"], "mc_samples"),
    ([*T, "--algo", "ac-teach", "--set", "switch_sign=both"], "switch_sign"),
    # --out: a file, an unwritable place, a finished run, the grid's folder
    ([*T, "--out", "BROKEN/a_file"], "is a file"),
    ([*T, "--out", "/proc/no/such/place"], "cannot write the run folder"),
    ([*T, "--out", "RUN"], "holds a finished run"),
    ([*T, "--out", "GRID"], "is not empty"),
    ([*T, "--out", "BROKEN"], "is not empty"),
    # tlac train --resume
    (["train", "--resume", "/no/such/run"], "does not exist"),
    (["train", "--resume", "RUN"], "is a finished run; nothing to resume"),
    (["train", "--resume", "BROKEN"], "config.yaml is missing"),
    (["train", "--resume", "BROKEN/bad_config_run"], "config.yaml"),
    (["train", "--checkpoint-every", "0"], "--checkpoint-every"),
    # tlac eval
    (["eval", "/no/such/run"], "does not exist"),
    (["eval", "BROKEN"], "config.yaml is missing"),
    (["eval", "BROKEN/a_file"], "a_file"),
    (["eval", "BROKEN/bad_config_run"], "config.yaml"),
    (["eval", "BROKEN/empty_config_run"], "config.yaml"),
    (["eval", "BROKEN/empty_model_run"], "model.pt"),
    (["eval", "BROKEN/garbage_model_run"], "model.pt"),
    (["eval", "BROKEN/truncated_model_run"], "model.pt"),
    (["eval", "BROKEN/no_model_run"], "has no trained model"),
    (["eval", "BROKEN/bad_algo_run"], "'sac'"),
    (["eval", "RUN", "--episodes", "0"], "--episodes"),
    (["eval", "RUN", "--episodes", "-2"], "--episodes"),
    (["eval", "RUN", "--seed", "-1"], "--seed"),
    (["eval", "GRID"], "config.yaml is missing"),
    # tlac report
    (["report", "/no/such/folder"], "/no/such/folder"),
    (["report", "BROKEN/a_file"], "a_file"),
    (["report", "BROKEN/bad_config_run"], "config.yaml'"),
    (["report", "BROKEN/bad_algo_run"], "config.yaml': unknown algorithm 'sac'"),
    (["report", "BROKEN/bad_experiment_yaml"], "experiment.yaml"),
    (["report", "BROKEN/no_experiment_yaml"], "experiment.yaml"),
    (["report", "BROKEN/bad_episodes_csv"], "episodes.csv"),
    # tlac experiment run / list
    (["experiment", "run", "/no/such.yaml", "--out", "NEW"], "/no/such.yaml"),
    (["experiment", "run", "BROKEN/garbage.yaml", "--out", "NEW"], "garbage.yaml"),
    (["experiment", "run", "BROKEN/list.yaml", "--out", "NEW"], "list.yaml"),
    (["experiment", "run", "BROKEN/empty.yaml", "--out", "NEW"], "empty.yaml"),
    (["experiment", "run", "BROKEN/no_domain.yaml", "--out", "NEW"], "domain"),
    (["experiment", "run", "BROKEN/bad_domain.yaml", "--out", "NEW"], "'atari'"),
    (["experiment", "run", "BROKEN/bad_steps.yaml", "--out", "NEW"], "steps"),
    (["experiment", "run", "BROKEN/nan_steps.yaml", "--out", "NEW"], "steps"),
    (["experiment", "run", "BROKEN/bad_seeds.yaml", "--out", "NEW"], "seeds"),
    (["experiment", "run", "BROKEN/zero_seeds.yaml", "--out", "NEW"], "seeds"),
    (["experiment", "run", "BROKEN/unknown_key.yaml", "--out", "NEW"], "stepz"),
    (["experiment", "run", "BROKEN/bad_algo.yaml", "--out", "NEW"], "'sac'"),
    (["experiment", "run", "BROKEN/no_algos.yaml", "--out", "NEW"], "algorithms"),
    (["experiment", "run", "BROKEN/bad_teacher.yaml", "--out", "NEW"], "'wizard'"),
    (["experiment", "run", "BROKEN/nan_override.yaml", "--out", "NEW"], "learning_rate"),
    (["experiment", "run", "BROKEN/neg_override.yaml", "--out", "NEW"], "clip_range must be > 0"),
    (["experiment", "run", "BROKEN/unknown_override.yaml", "--out", "NEW"], "'wings'"),
    (["experiment", "run", str(TINY), "--out", "NEW", "--workers", "0"], "--workers"),
    (["experiment", "run", str(TINY), "--out", "NEW", "--workers", "-1"], "--workers"),
    (["experiment", "run", str(TINY), "--out", "NEW", "--workers", "two"], "--workers"),
    (
        ["experiment", "run", str(TINY), "--out", "NEW", "--backend", "slurm"],
        "invalid choice: 'slurm'",
    ),
    (["experiment", "run", str(TINY), "--out", "RUN"], "not a grid folder"),
    (["experiment", "run", str(TINY), "--out", "/proc/no/such"], "cannot create the grid folder"),
    (["experiment", "run", str(TINY), "--out", "BROKEN/a_file"], "a_file"),
    (["experiment", "run", str(TINY), "--out", "NEW", "--address", "auto"], "--address needs"),
    (["experiment", "list", "/no/such.yaml"], "/no/such.yaml"),
    (["experiment", "list", "BROKEN/garbage.yaml"], "garbage.yaml"),
    # tlac teacher
    (["teacher", "eval", "atari"], "unknown environment 'atari'"),
    (["teacher", "eval", "doorkey", "--teachers", "wizard"], "'wizard'"),
    (["teacher", "eval", "doorkey", "--teachers", ",,"], "--teachers"),
    (["teacher", "eval", "doorkey", "--episodes", "0"], "--episodes"),
    (["teacher", "eval", "doorkey", "--n-envs", "0"], "--n-envs"),
    (["teacher", "train", "pickplace", "--steps", "10"], "'pickplace'"),
    (["teacher", "train", "hopper-bullet", "--steps", "0"], "--steps"),
    (["teacher", "train", "hopper-bullet", "--time-limit", "-5"], "--time-limit"),
    # no command, unknown command
    (["fly"], "invalid choice: 'fly'"),
]


def one_line_error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run the CLI; assert exit status 2 and one line on stderr, no traceback; return it."""
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize(
    ("args", "fragment"), CLI_CASES, ids=[" ".join(a)[:80] for a, _ in CLI_CASES]
)
def test_cli_bad_input_is_one_line_and_exit_2(args, fragment, made, scratch, capsys):
    before_run, before_grid = _tree(made["run"]), _tree(made["grid"])
    args = _placeholders(args, made)
    fragment = _placeholders([fragment], made)[0]
    line = one_line_error(args, capsys)
    assert fragment in line, line
    assert _tree(made["run"]) == before_run
    assert _tree(made["grid"]) == before_grid
    assert not (scratch / "runs").exists() or not any((scratch / "runs").rglob("result.json"))


# --------------------------------------------------------------------------- the Python API
def _pendulum():
    import gymnasium as gym

    return gym.make("Pendulum-v1")


def _swing(obs):
    return np.array([1.0], dtype=np.float32)


def _api_cases() -> list[tuple[str, object, str]]:
    from tlac import TLAC
    from tlac.baselines.ac_teach import ACTeach
    from tlac.baselines.dqn_tlql import DQNTLQL

    def tlac(**kw):
        return lambda: TLAC("doorkey", teachers=["optimal"], **kw)

    def learn(teacher, steps=1100):
        # (past the audition: Pendulum's first 5 episodes, 1,000 steps, are the student's
        # alone, and the teacher is first asked when it leads the next one)
        def go():
            TLAC(_pendulum(), teachers=[teacher], seed=0, n_steps=16, batch_size=16).learn(
                steps, progress_bar=False
            )

        return go

    def boom(obs):
        raise RuntimeError("sensor offline")

    cases: list[tuple[str, object, str]] = [
        ("env atari", lambda: TLAC("atari"), "unknown environment 'atari'"),
        ("env number", lambda: TLAC(42), "env"),
        ("env None", lambda: TLAC(None), "env"),
        ("teacher name", lambda: TLAC("doorkey", teachers=["wizard"]), "'wizard'"),
        (
            "teacher names without a domain",
            lambda: TLAC(_pendulum(), teachers=["optimal"]),
            "optimal",
        ),
        ("teacher a number", lambda: TLAC(_pendulum(), teachers=[5]), "teacher"),
        ("seed -1", tlac(seed=-1), "seed"),
        ("seed 1.5", tlac(seed=1.5), "seed"),
        ("seed text", tlac(seed="zero"), "seed"),
        ("lr nan", tlac(learning_rate=float("nan")), "learning_rate must be a finite"),
        ("lr inf", tlac(learning_rate=float("inf")), "learning_rate must be a finite"),
        ("lr -1", tlac(learning_rate=-1.0), "learning_rate must be > 0"),
        ("lr text", tlac(learning_rate="fast"), "learning_rate"),
        ("n_steps 0", tlac(n_steps=0), "n_steps"),
        ("n_steps 2.5", tlac(n_steps=2.5), "n_steps"),
        ("batch_size > rollout", tlac(batch_size=999), "batch_size 999 exceeds"),
        ("variant", tlac(variant="exact"), "'exact'"),
        ("removed setting", tlac(trust="max"), "unknown TL-AC setting 'trust'"),
        ("unknown setting", tlac(wings=2), "'wings'"),
        ("normalize_advantage text", tlac(normalize_advantage="yes"), "true or false"),
        ("preset unknown", tlac(preset="nowhere"), "nowhere"),
        ("teacher returns None", learn(lambda obs: None), "teacher 'teacher0' returned None"),
        ("teacher returns text", learn(lambda obs: "left"), "returned 'left'"),
        ("teacher raises", learn(boom), "teacher 'boom' raised RuntimeError: sensor offline"),
        ("teacher returns NaN", learn(lambda obs: np.array([np.nan], np.float32)), "NaN"),
        ("teacher out of the box", learn(lambda obs: np.array([9.0], np.float32)), "outside"),
        ("learn 0", lambda: TLAC("doorkey").learn(0), "total_timesteps"),
        ("learn -5", lambda: TLAC("doorkey").learn(-5), "total_timesteps"),
        ("learn 1.5", lambda: TLAC("doorkey").learn(1.5), "total_timesteps"),
        ("predict wrong shape", lambda: TLAC("doorkey").predict(np.zeros(294)), "shape (294,)"),
        ("predict nan", lambda: TLAC("doorkey").predict(np.full(147, np.nan)), "NaN"),
        ("predict text", lambda: TLAC("doorkey").predict("obs"), "numeric"),
        ("load missing", lambda: TLAC.load("/no/such/model.pt"), "/no/such/model.pt"),
        (
            "dqn-tlql lr nan",
            lambda: DQNTLQL(None, learning_rate=float("nan")),
            "learning_rate must be a finite",
        ),
        ("dqn-tlql unknown", lambda: DQNTLQL(None, wings=1), "'wings'"),
        ("ac-teach keep prob", lambda: ACTeach(None, dropout_keep_prob=1.5), "dropout_keep_prob"),
        ("ac-teach nan tau", lambda: ACTeach(None, tau=float("nan")), "tau must be a finite"),
    ]
    return cases


API_CASES = _api_cases()


@pytest.mark.parametrize(("name", "make", "fragment"), API_CASES, ids=[c[0] for c in API_CASES])
def test_api_bad_input_raises_a_tlac_error(name, make, fragment, made):
    before_run = _tree(made["run"])
    with pytest.raises(TlacError) as info:
        make()
    assert fragment in str(info.value), str(info.value)
    assert _tree(made["run"]) == before_run


@pytest.mark.parametrize(
    "broken",
    ["empty_model_run", "garbage_model_run", "truncated_model_run", "sb3.zip", "a_file"],
)
def test_api_load_of_a_broken_file_is_one_error(broken, made):
    from tlac import TLAC

    target = made["broken"] / broken
    path = target / "model.pt" if target.is_dir() else target
    # SB3's zip (its "data" at the top) is named as one: TL-AC takes it as a teacher
    expected = "is a stable-baselines3 model" if broken == "sb3.zip" else "not a loadable TL-AC"
    with pytest.raises(TlacError, match=expected):
        TLAC.load(path)


def test_the_suite_is_as_large_as_promised():
    assert len(CLI_CASES) + len(API_CASES) + 5 >= 150


def test_teachers_given_as_one_string_are_refused():
    from tlac import TLAC

    with pytest.raises(TlacError, match=r"did you mean \['optimal'\]"):
        TLAC("doorkey", teachers="optimal")
