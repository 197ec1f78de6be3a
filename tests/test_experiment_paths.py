"""Paths in an experiment file resolve against the file's folder, not the working directory
(issue 43, point 5): ``domain: my_domain.py:DOMAIN`` beside the YAML works from any cwd, the
copy in ``DIR/experiment.yaml`` names the same file, and a missing file names both places."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tlac.errors import ConfigError
from tlac.experiments.config import declared_domain_name, load_config, parse_config
from tlac.experiments.grid import expand_grid
from tlac.experiments.runner import prepare_out_dir, spec_mismatch, with_recorded_domain
from tlac.run import RunSpec

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "my_domain.py"
GRID = (
    "name: mine\nsteps: 256\nseeds: 1\n"
    "teacher_sets:\n  pd-random: {teachers: [pd, random]}\n"
    "algorithms:\n  - name: tlac\n"
)


def experiment(folder: Path, domain: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "grid.yaml"
    path.write_text(f"domain: {domain}\n{GRID}")
    return path


@pytest.fixture
def elsewhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A working directory that is not the experiment file's folder."""
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    return cwd


def test_a_domain_file_beside_the_yaml_loads_from_another_cwd(
    tmp_path: Path, elsewhere: Path
) -> None:
    config_path = experiment(tmp_path / "exp", "my_domain.py:DOMAIN")
    shutil.copy(EXAMPLE, tmp_path / "exp" / "my_domain.py")
    config = load_config(config_path)
    assert config.domain == f"{tmp_path / 'exp' / 'my_domain.py'}:DOMAIN"
    assert [r.name for r in expand_grid(config)] == ["cartpole-pd__pd-random__tlac__seed0"]
    assert expand_grid(config)[0].spec.env == config.domain  # what the workers import
    # a subfolder and '..' resolve against the file's folder too
    (tmp_path / "domains").mkdir()
    shutil.copy(EXAMPLE, tmp_path / "domains" / "mine.py")
    config = load_config(experiment(tmp_path / "exp2", "../domains/mine.py:DOMAIN"))
    assert config.domain == f"{tmp_path / 'domains' / 'mine.py'}:DOMAIN"


def test_absolute_paths_modules_and_names_are_unchanged(elsewhere: Path) -> None:
    config = load_config(experiment(elsewhere / "a", f"{EXAMPLE}:DOMAIN"))
    assert config.domain == f"{EXAMPLE}:DOMAIN"
    data = yaml.safe_load(f"domain: doorkey\n{GRID}".replace("pd, random", "optimal"))
    assert parse_config(data, "mem.yaml").domain == "doorkey"


def test_the_copy_in_DIR_names_the_same_file(tmp_path: Path, elsewhere: Path) -> None:
    config_path = experiment(tmp_path / "exp", "my_domain.py:DOMAIN")
    shutil.copy(EXAMPLE, tmp_path / "exp" / "my_domain.py")
    config = load_config(config_path)
    out = prepare_out_dir(config, tmp_path / "results" / "mine")
    copy = yaml.safe_load((out / "experiment.yaml").read_text())
    assert copy["domain"] == "../../exp/my_domain.py:DOMAIN"  # relative to DIR: moves with it
    assert load_config(out / "experiment.yaml").domain == config.domain  # what tlac report reads


def test_a_missing_domain_file_names_both_places(tmp_path: Path, elsewhere: Path) -> None:
    config_path = experiment(tmp_path / "exp", "my_domain.py:DOMAIN")
    beside = tmp_path / "exp" / "my_domain.py"
    with pytest.raises(ConfigError) as info:
        load_config(config_path)
    message = str(info.value)
    assert message.startswith(f"{config_path}: field 'domain': domain file 'my_domain.py'")
    assert str(beside) in message and f"nor {elsewhere / 'my_domain.py'}" in message
    # only in the working directory: refused, with the path to write instead
    shutil.copy(EXAMPLE, elsewhere / "my_domain.py")
    with pytest.raises(ConfigError) as info:
        load_config(config_path)
    message = str(info.value)
    assert str(beside) in message and f"{elsewhere / 'my_domain.py'} exists" in message
    assert "write '../elsewhere/my_domain.py:DOMAIN'" in message


def test_a_finished_run_of_a_moved_domain_file_still_counts() -> None:
    spec = RunSpec(env="/new/place/my_domain.py:DOMAIN", teachers=["pd"], steps=256)
    done = {"env": "/old/place/my_domain.py:DOMAIN", "teacher_kinds": ["pd"], "steps": 256}
    assert spec_mismatch(spec, yaml.safe_dump(done).encode()) is None
    done["env"] = "/old/place/my_domain.py:OTHER"
    assert spec_mismatch(spec, yaml.safe_dump(done).encode()).startswith("env=")


def test_tlac_experiment_list_from_another_cwd(tmp_path: Path, elsewhere: Path) -> None:
    config_path = experiment(tmp_path / "exp", "my_domain.py:DOMAIN")
    shutil.copy(EXAMPLE, tmp_path / "exp" / "my_domain.py")
    relative = os.path.relpath(config_path, elsewhere)
    proc = subprocess.run(
        [sys.executable, "-m", "tlac.cli", "experiment", "list", relative],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "cartpole-pd__pd-random__tlac__seed0" in proc.stdout


def test_a_domain_files_name_is_read_without_importing_it(tmp_path: Path) -> None:
    """What reports and listings do (issue 44): the Domain's name from the grid's
    domain.json, else from the file's source (a literal name=...), never by running it."""
    assert declared_domain_name(f"{EXAMPLE}:DOMAIN") == "cartpole-pd"
    assert declared_domain_name(f"{EXAMPLE}:OTHER") is None
    assert declared_domain_name("no/such/file.py:DOMAIN") is None
    data = yaml.safe_load(f"domain: gone.py:DOMAIN\n{GRID}")
    config = parse_config(data, str(tmp_path / "grid.yaml"), import_domain=False)
    assert config.domain == f"{tmp_path / 'gone.py'}:DOMAIN" and config.domain_name is None
    with pytest.raises(ConfigError, match="recorded when the grid is trained"):
        expand_grid(config)
    record = tmp_path / "domain.json"
    record.write_text(json.dumps({"domain": "/moved/from/gone.py:DOMAIN", "name": "mine"}))
    runs = expand_grid(with_recorded_domain(config, tmp_path))
    assert [r.name for r in runs] == ["mine__pd-random__tlac__seed0"]
    record.write_text(json.dumps({"domain": "/moved/from/other.py:DOMAIN", "name": "mine"}))
    assert with_recorded_domain(config, tmp_path).domain_name is None  # another domain's
    record.write_text(json.dumps({"domain": "gone.py:DOMAIN", "name": "../up"}))
    with pytest.raises(ConfigError, match=r"domain.json'.*expected"):
        with_recorded_domain(config, tmp_path)
