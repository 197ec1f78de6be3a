"""Gymnasium ids of the built-in domains, and a domain of your own (issue 11, item 3): from
Python (register_domain), from `tlac train --env FILE.py:ATTR` and from an experiment config."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import tlac
from tlac import TLAC
from tlac.cli import main
from tlac.domains import domain_names, get_domain, register_domain
from tlac.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "my_domain.py"


def test_import_tlac_registers_the_domains_with_gymnasium() -> None:
    env = gym.make("tlac/DoorKey-v0")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (147,) and env.action_space.n == 6
    assert {"tlac/DoorKey-v0", "tlac/HopperBullet-v0", "tlac/PickPlace-v0"} <= set(gym.registry)


def test_a_registered_domain_works_by_name_from_python() -> None:
    example = get_domain(f"{EXAMPLE}:DOMAIN")  # imported from the file
    mine = tlac.register_domain(dataclasses.replace(example, name="my-cartpole"), replace=True)
    assert "my-cartpole" in domain_names() and mine.presets["tlac"] == "default"
    model = TLAC("my-cartpole", teachers=["pd", "random"], seed=0, n_steps=16, batch_size=16)
    model.learn(512, progress_bar=False)
    assert model.num_timesteps >= 512 and model.teacher_names == ["pd", "random"]
    assert gym.make("tlac/my-cartpole-v0").reset(seed=0)[0].shape == (4,)


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        ({"name": "doorkey"}, "exists already"),
        ({"name": ""}, "letters, digits"),
        ({"name": "a:b"}, "letters, digits"),
        ({"name": "my domain"}, "letters, digits"),
        ({"make_env": 3}, "make_env must be callable"),
        ({"teacher_names": ()}, "teacher_names must be a non-empty tuple"),
    ],
)
def test_bad_domains_are_refused(bad: dict, match: str) -> None:
    example = get_domain(f"{EXAMPLE}:DOMAIN")
    with pytest.raises(ConfigError, match=match):
        register_domain(dataclasses.replace(example, **bad))
    with pytest.raises(ConfigError, match=r"takes a tlac\.domains\.Domain"):
        register_domain("doorkey")  # type: ignore[arg-type]


def test_a_domain_file_that_is_not_there_or_not_a_domain() -> None:
    with pytest.raises(ConfigError, match="cannot import"):
        get_domain("no/such/file.py:DOMAIN")
    with pytest.raises(ConfigError, match=r"is not a tlac\.domains\.Domain"):
        get_domain(f"{EXAMPLE}:pd_controller")


def test_tlac_train_and_an_experiment_config_take_a_domain_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The commands that train import a domain file; `tlac experiment list` and `tlac report`
    do not (issue 44): they name the runs after the Domain's name the grid recorded."""
    marker = tmp_path / "code-ran"
    mine = tmp_path / "mine.py"
    source = EXAMPLE.read_text().replace('name="cartpole-pd"', 'name="cartpole-" + "pd"')
    mine.write_text(source + f"\nopen({str(marker)!r}, 'w').close()  # proof of an import\n")
    out = tmp_path / "run"
    cli = [sys.executable, "-m", "tlac.cli"]
    proc = subprocess.run(
        [
            *cli,
            "train",
            "--env",
            f"{mine}:DOMAIN",
            "--steps",
            "256",
            "--out",
            str(out),
            "--no-progress",
            "--eval-episodes",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert (out / "result.json").exists() and "left" in (out / "teacher_usage.csv").read_text()
    config = tmp_path / "grid.yaml"
    config.write_text(
        "name: mine\ndomain: mine.py:DOMAIN\nsteps: 256\nseeds: 1\n"
        "teacher_sets:\n  pd-random: {teachers: [pd, random]}\n"
        "algorithms:\n  - name: tlac\n"
    )
    marker.unlink()
    assert main(["experiment", "list", str(config)]) == 0
    assert "not yet trained" in capsys.readouterr().out  # no literal name="..." to read
    assert not marker.exists()
    grid = tmp_path / "grid"
    proc = subprocess.run(
        [*cli, "experiment", "run", str(config), "--out", str(grid), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert marker.exists()
    assert [p.name for p in (grid / "runs").iterdir()] == ["cartpole-pd__pd-random__tlac__seed0"]
    assert (grid / "runs" / "cartpole-pd__pd-random__tlac__seed0" / "result.json").exists()
    marker.unlink()
    assert main(["experiment", "list", str(config), "--out", str(grid)]) == 0
    assert "finished  cartpole-pd__pd-random__tlac__seed0" in capsys.readouterr().out
    assert main(["report", str(grid)]) == 0
    assert (grid / "report.md").is_file()
    assert not marker.exists()
