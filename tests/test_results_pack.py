"""``tlac results pack DIR``: the run folders of an experiment folder into one deterministic
``DIR/runs.tar.xz`` holding only what the reports read, which the report, ``tlac experiment
list`` and a resumed grid read directly (issue 43, point 6).

The study is the synthetic grid of the report's golden test (finished, failed, partial and
missing runs; no training), with the files a real run folder also has and nothing reads.
"""

from __future__ import annotations

import hashlib
import io
import os
import shutil
import tarfile
from pathlib import Path

import pytest
import yaml
from test_experiments import fake_finished_run
from test_report_golden import GOLDEN, make_experiment

from tlac.cli import main
from tlac.errors import ConfigError
from tlac.experiments.archive import ARCHIVE_FILE, KEPT_FILES, RunStore, read_archive
from tlac.experiments.config import load_config
from tlac.experiments.grid import ERROR_FILE
from tlac.experiments.packing import pack_study
from tlac.experiments.report import write_report
from tlac.experiments.rundata import EPISODES_FILE, EVAL_FILE, USAGE_FILE
from tlac.experiments.runner import run_local
from tlac.run import RESULT_FILE

UNREAD = ("monitor.csv", "progress.csv", "model.pt", "model.zip", "checkpoint.pt")
"""Files of a run folder that no report reads: packing leaves them out."""


def make_study(out: Path) -> Path:
    """The golden test's synthetic grid, each run folder with a ``config.yaml`` and files
    nothing reads as well."""
    make_experiment(out)
    for folder in (out / "runs").iterdir():
        (folder / "config.yaml").write_text(f"env: doorkey\nrun: {folder.name}\n")
        for name in UNREAD:
            (folder / name).write_bytes(b"not read by any report\n" * 10)
    return out


def report_files(out: Path) -> dict[str, bytes]:
    """Every file ``tlac report`` wrote into ``out``, by relative path."""
    names = ["report.md", "summary.csv", "jumpstart.csv"]
    names += [f"figures/{p.name}" for p in sorted((out / "figures").iterdir())]
    return {n: (out / n).read_bytes() for n in names}


def tlac(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_packed_study_gives_the_same_report_and_listing(tmp_path: Path, capsys) -> None:
    plain = make_study(tmp_path / "plain")
    packed = make_study(tmp_path / "packed")
    code, out, err = tlac(capsys, "results", "pack", str(packed))
    assert code == 0, err
    assert out.startswith("packed 11 runs (1 failed, 9 finished, 1 partial) into ")
    assert not (packed / "runs").exists() and (packed / ARCHIVE_FILE).is_file()

    write_report(plain)
    write_report(packed)
    assert report_files(packed) == report_files(plain)
    sha = {n: hashlib.sha256((packed / n).read_bytes()).hexdigest() for n in GOLDEN[False]}
    assert sha == GOLDEN[False]

    listings = []
    for study in (plain, packed):
        code, out, _ = tlac(
            capsys, "experiment", "list", str(study / "experiment.yaml"), "--out", str(study)
        )
        assert code == 0
        listings.append(out)
    assert listings[0] == listings[1]
    assert "  missing   doorkey__none__ppo__seed2" in listings[1]
    assert "  partial   doorkey__lr__ucb__seed2" in listings[1]


def test_the_archive_is_deterministic_and_holds_only_what_reports_read(tmp_path: Path) -> None:
    first = make_study(tmp_path / "first")
    second = make_study(tmp_path / "second")
    for path in (second / "runs").rglob("*"):  # other times and modes: the same archive
        os.utime(path, (1_700_000_000, 1_700_000_000))
        if path.is_file():
            path.chmod(0o600)
    pack_study(first)
    pack_study(second)
    data = (first / ARCHIVE_FILE).read_bytes()
    assert data == (second / ARCHIVE_FILE).read_bytes()

    with tarfile.open(fileobj=io.BytesIO(data), mode="r:xz") as tar:
        members = tar.getmembers()
    names = [m.name for m in members]
    assert names == sorted(names) and names[0] == "runs"
    files = {Path(n).name for n in names if n.count("/") == 2}
    assert files == set(KEPT_FILES)  # error.txt from the failed run
    read = {EPISODES_FILE, EVAL_FILE, USAGE_FILE, RESULT_FILE, ERROR_FILE, "config.yaml"}
    assert read == set(KEPT_FILES)  # what rundata and the runner's settings check read
    assert not files & set(UNREAD)
    assert {(m.mtime, m.uid, m.gid, m.uname, m.gname) for m in members} == {(0, 0, 0, "", "")}
    assert {m.mode for m in members if m.isfile()} == {0o644}
    assert {m.mode for m in members if m.isdir()} == {0o755}
    # the folder of the partial run (empty) is kept, so that it stays partial
    assert "runs/doorkey__lr__ucb__seed2" in names


@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda d: d, "is not a folder"),
        (lambda d: (d.mkdir(), (d / "runs").mkdir()), "is not an experiment folder"),
        (lambda d: d.write_text("x"), "is not a folder"),
        (
            lambda d: (make_study(d), (d / "runs" / "notes.txt").write_text("x")),
            "notes.txt' is not a run folder",
        ),
    ],
    ids=["missing", "no-experiment-file", "a-file", "stray-file-in-runs"],
)
def test_a_bad_dir_exits_2_with_one_line(tmp_path: Path, capsys, make, fragment) -> None:
    study = tmp_path / "study"
    make(study)

    def tree() -> list[Path]:  # the folder's lock file (.lock, as the runner's) aside
        return sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.name != ".lock")

    before = tree()
    code, out, err = tlac(capsys, "results", "pack", str(study))
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and err.startswith("tlac: error: ")
    assert fragment in err
    assert tree() == before


def test_new_runs_are_merged_into_the_archive_a_folder_winning(tmp_path: Path) -> None:
    """A study packed with part of its runs (one of them failed then), then given the rest as
    folders (the failed run redone), packs into the very archive of the whole study."""
    whole = make_study(tmp_path / "whole")
    grown = make_study(tmp_path / "grown")
    later = tmp_path / "later"
    later.mkdir()
    for name in ("doorkey__lr__tlac__seed1", "doorkey__none__ppo__seed0"):
        shutil.move(grown / "runs" / name, later / name)
    redone = "doorkey__1optimal__tlac__seed2"
    shutil.move(grown / "runs" / redone, later / redone)
    (grown / "runs" / redone).mkdir()
    (grown / "runs" / redone / "error.txt").write_text("Traceback\nRuntimeError: first try\n")
    pack_study(grown)
    assert RunStore(grown).status(redone) == "failed"

    (grown / "runs").mkdir()  # what 'tlac experiment run' does before redoing runs
    for folder in later.iterdir():
        shutil.move(folder, grown / "runs" / folder.name)
    store = RunStore(grown)
    assert store.status(redone) == "finished"  # the folder wins over the archive's copy
    assert store.status("doorkey__1optimal__tlac__seed0") == "finished"  # from the archive
    names = sorted(p.name for p in (whole / "runs").iterdir())
    before = {n: (store.status(n), store.read(n, "episodes.csv")) for n in names}

    summary = pack_study(grown)
    assert summary.from_folders == 3 and summary.from_archive == 8
    assert (grown / ARCHIVE_FILE).read_bytes() == pack_study(whole).archive.read_bytes()
    store = RunStore(grown)
    assert {n: (store.status(n), store.read(n, "episodes.csv")) for n in names} == before


def test_a_resumed_grid_skips_the_packed_finished_runs(tmp_path: Path) -> None:
    """A finished run that is only in the archive is not redone, and its settings are still
    checked against a changed experiment file."""
    data = {
        "domain": "doorkey",
        "steps": 300,
        "seeds": [0],
        "eval": {"episodes": 0},
        "teacher_eval_episodes": 0,
        "teacher_sets": {"1optimal": ["optimal"]},
        "algorithms": [{"name": "tlac"}],
    }
    (tmp_path / "a.yaml").write_text(yaml.safe_dump(data))
    config = load_config(tmp_path / "a.yaml")
    out = tmp_path / "out"
    run_name = fake_finished_run(config, out).name
    (out / "experiment.yaml").write_text(yaml.safe_dump(data))
    pack_study(out)
    assert read_archive(out / ARCHIVE_FILE)[run_name]["result.json"] == b'{"finished": true}'

    summary = run_local(config, out, workers=1, live=False)
    assert summary.skipped == 1 and not summary.finished
    assert list((out / "runs").iterdir()) == []  # nothing redone

    data["steps"] = 400
    (tmp_path / "b.yaml").write_text(yaml.safe_dump(data))
    changed = load_config(tmp_path / "b.yaml")
    with pytest.raises(
        ConfigError, match=rf"runs\.tar\.xz:runs/{run_name}: finished with steps=300"
    ):
        run_local(changed, out, workers=1, live=False)


def test_a_damaged_archive_is_one_error_line(tmp_path: Path, capsys) -> None:
    study = make_study(tmp_path / "study")
    pack_study(study)
    archive = study / ARCHIVE_FILE
    archive.write_bytes(archive.read_bytes()[:200])
    code, _, err = tlac(capsys, "report", str(study))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "runs.tar.xz: not a readable runs archive" in err
