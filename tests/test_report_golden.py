"""Golden test of ``tlac report``: a small synthetic experiment folder (no training) whose
``report.md`` and CSVs must keep the exact bytes they had when the report was split into
tables, Markdown and figures (issue 12). Any change to the report's numbers or wording shows
up here; when a change is intended, check the new text by eye and update the hashes.

The folder exercises every part of the report: a labelled teacher set and one matching a
paper row, TL-AC with its learned high level, a labelled TL-AC with UCB1 (the ablation
section), the no-advice baseline, a threshold, evaluations, usage logs with regions, a
teacher without measured return, and failed, partial and missing runs.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import yaml

from tlac.experiments.report import write_report

EXPERIMENT = {
    "name": "golden",
    "description": "A synthetic grid for the report's golden test.",
    "domain": "doorkey",
    "steps": 1200,
    "seeds": 3,
    "log_interval": 100,
    "eval": {"every": 400, "episodes": 4},
    "metrics": {
        "jumpstart_window": 300,
        "final_window": 400,
        "threshold": 0.5,
        "curve_points": 6,
        "bootstrap_reps": 200,
        "bootstrap_seed": 3,
    },
    "teacher_sets": {
        "1optimal": ["optimal"],
        "lr": {"label": "Teacher L + Teacher R", "teachers": ["L", "R"]},
    },
    "algorithms": [
        {"name": "tlac"},
        {"name": "tlac", "selector": "ucb1", "label": "ucb", "teacher_sets": ["lr"]},
        {"name": "ppo"},
    ],
}
TEACHERS = {
    "optimal": {"mean": 0.95, "std": 0.05, "episodes": 20},
    "L": {"mean": 0.5},
    "R": {"std": 0.1, "episodes": 20},  # no measured mean: left out of the table
}
STEPS = (150, 300, 450, 600, 750, 900, 1050, 1200)
GOLDEN = {
    False: {
        "report.md": "0a871d4336c53da3e6607812bc113061179e6971daeeb39ea31091c5b86c1a2c",
        "summary.csv": "d8d0312c9914499ab3d8889847cae4958576811cd65d54afbbcb6931c793d54c",
        "jumpstart.csv": "c32248f471489a5d0d1bbddb894fffebc8637358c849ae3e64eecbdd6d22ccac",
    },
    True: {
        "report.md": "b27a951856bfe5bcd750232b59edc64c1ac3feff6c0976a7b3f7ae115ec8d257",
        "summary.csv": "d8d0312c9914499ab3d8889847cae4958576811cd65d54afbbcb6931c793d54c",
        "jumpstart.csv": "c0c723cbd5d8e08980c831a97130a3ed0d1dbe038a802c2d07f621d83f2b21a5",
    },
}
"""sha256 of the files the report writes, with ``--paper`` (True) and without; taken from the
report as it was before the split (commit 3fe04a5) and unchanged by it."""
FIGURES = [
    "ablation.png",
    "curves.png",
    "iqm.png",
    "profiles.png",
    "student_alone.png",
    "usage__1optimal__tlac.png",
    "usage__lr__tlac.png",
    "usage__lr__ucb.png",
]


def _returns(level: float, slope: float, seed: int) -> list[float]:
    """A deterministic, slightly seed-dependent learning curve over STEPS."""
    return [round(min(1.0, level + slope * i + 0.03 * ((seed + i) % 3)), 4) for i in range(8)]


def _finished_run(folder: Path, returns: list[float], evals: list[float], usage: bool) -> None:
    folder.mkdir(parents=True)
    rows = [f"{t},{r},{10 + i}" for i, (t, r) in enumerate(zip(STEPS, returns, strict=True))]
    (folder / "episodes.csv").write_text("timestep,return,length\n" + "\n".join(rows) + "\n")
    ev = [f"{t},{v},0.1,4" for t, v in zip((0, 400, 800, 1200), evals, strict=True)]
    (folder / "eval.csv").write_text(
        "timestep,mean_return,std_return,episodes\n" + "\n".join(ev) + "\n"
    )
    lines = ["timestep,region,choice,count,fraction"]
    if usage:
        for k, t in enumerate((400, 800, 1200)):
            for region, teacher in (("all", "optimal"), ("near", "L"), ("far", "R")):
                lines += [f"{t},{region},{teacher},{6 - k},0", f"{t},{region},agent,{2 + k},0"]
    (folder / "teacher_usage.csv").write_text("\n".join(lines) + "\n")
    result = {"finished": True, "steps": 1200, "final_eval_mean": evals[-1], "wall_time_s": 2.5}
    (folder / "result.json").write_text(json.dumps(result))


def make_experiment(out: Path) -> Path:
    runs = out / "runs"
    runs.mkdir(parents=True)
    (out / "experiment.yaml").write_text(yaml.safe_dump(EXPERIMENT, sort_keys=False))
    (out / "teachers.json").write_text(json.dumps(TEACHERS))
    for seed in range(3):
        name = f"doorkey__1optimal__tlac__seed{seed}"
        _finished_run(runs / name, _returns(0.4, 0.08, seed), [0, 0.3, 0.7, 0.9], usage=True)
        name = f"doorkey__lr__tlac__seed{seed}"
        _finished_run(runs / name, _returns(0.1, 0.05, seed), [0, 0.2, 0.4, 0.6], usage=True)
        if seed < 2:  # seed 2 of the baseline is missing
            name = f"doorkey__none__ppo__seed{seed}"
            _finished_run(runs / name, _returns(0.0, 0.01, seed), [0, 0, 0.1, 0.1], usage=False)
    _finished_run(
        runs / "doorkey__lr__ucb__seed0", _returns(0.2, 0.02, 0), [0, 0.1, 0.2, 0.2], usage=True
    )
    (runs / "doorkey__lr__ucb__seed1").mkdir()
    (runs / "doorkey__lr__ucb__seed1" / "error.txt").write_text(
        "Traceback\nRuntimeError: synthetic\n"
    )
    (runs / "doorkey__lr__ucb__seed2").mkdir()  # partial: neither result nor error
    return out


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("paper", [False, True], ids=["plain", "paper"])
def test_report_bytes_match_the_golden_hashes(tmp_path: Path, paper: bool) -> None:
    out = make_experiment(tmp_path / "golden")
    text = write_report(out, paper=paper).read_text()
    got = {name: _sha(out / name) for name in GOLDEN[paper]}
    assert got == GOLDEN[paper], "report changed; its text now:\n" + text
    assert sorted(p.name for p in (out / "figures").iterdir()) == FIGURES


BARE = {
    "name": "bare",
    "domain": "doorkey",
    "steps": 1200,
    "seeds": 2,
    "eval": {"episodes": 0},
    "teacher_sets": {"1optimal": ["optimal"], "lr": ["L", "R"]},
    "algorithms": [{"name": "tlac"}],
}
BARE_GOLDEN = {
    "report.md": "08acce376756d04beebe044fc014bf9cfa1b09a701418834d5ef301493c7443e",
    "summary.csv": "9c70e527b9d92e478fcc6f17e73d3055b99ed8dff277af18b4756e9753868b69",
}


def test_report_without_baseline_teachers_or_evaluations(tmp_path: Path) -> None:
    """The other branches: no baseline (no jumpstart, no jumpstart.csv), no teachers.json,
    no evaluation, a single advice algorithm (no comparison table) and a cell whose runs all
    failed."""
    out = tmp_path / "bare"
    runs = out / "runs"
    runs.mkdir(parents=True)
    (out / "experiment.yaml").write_text(yaml.safe_dump(BARE, sort_keys=False))
    for seed in range(2):
        name = f"doorkey__1optimal__tlac__seed{seed}"
        _finished_run(runs / name, _returns(0.3, 0.05, seed), [0, 0, 0, 0], usage=False)
        (runs / f"doorkey__lr__tlac__seed{seed}").mkdir()
        (runs / f"doorkey__lr__tlac__seed{seed}" / "error.txt").write_text("")
    text = write_report(out).read_text()
    got = {name: _sha(out / name) for name in BARE_GOLDEN}
    assert got == BARE_GOLDEN, "report changed; its text now:\n" + text
    assert not (out / "jumpstart.csv").exists()
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["curves.png", "iqm.png"]
