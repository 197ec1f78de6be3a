"""Soak test of exact resume: a long DoorKey run killed with SIGKILL at random points and resumed
ends with the files of the same run left alone.

Trains the default TL-AC on DoorKey (``tlac train``, its default teachers) twice into WORK: once
straight through (``straight/``) and once (``broken/``) killed with ``kill -9`` whenever its
episodes.csv passes one of ``--kills`` random steps, then continued, alternately with ``tlac
train --resume`` and with the same ``tlac train`` command again (both resume). Checkpoints every
``--checkpoint-every`` steps. Then compares every file of the two run folders: byte-identical,
model.pt included, except the wall-clock fields that docs/architecture.md lists (progress.csv's
``time/*`` rows, monitor.csv's start time and ``t`` column, result.json's ``wall_time_s`` and
``steps_per_s``). Writes a Markdown report (``--out``) and exits 1 on any difference.

    python benchmarks/soak_resume.py --steps 1000000 --checkpoint-every 50000 --kills 3 \\
        --out results/soak/resume-1e6.md

Not part of the test suite (two 1e6-step runs: about an hour on one core each); the quick
version of the same check is tests/test_untrusted_files.py.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

WALL_CLOCK = (
    "progress.csv time/* rows; monitor.csv t_start and t; result.json wall_time_s, steps_per_s"
)


def tlac(*args: str) -> list[str]:
    return [sys.executable, "-m", "tlac.cli", *args]


def last_step(episodes: Path) -> int:
    """The timestep of the last complete row of episodes.csv (0 before any)."""
    try:
        data = episodes.read_bytes()
    except OSError:
        return 0
    lines = data[: data.rfind(b"\n") + 1].splitlines()
    try:
        return int(lines[-1].split(b",")[0]) if len(lines) > 1 else 0
    except ValueError:
        return 0


def comparable(path: Path) -> object:
    """The content of a run file without its wall-clock fields."""
    if path.name == "progress.csv":
        return [ln for ln in path.read_text().splitlines() if ",time/" not in ln]
    if path.name == "monitor.csv":
        return [ln.rsplit(",", 1)[0] for ln in path.read_text().splitlines()[1:]]
    if path.name == "result.json":
        result = json.loads(path.read_text())
        return {k: v for k, v in result.items() if k not in ("wall_time_s", "steps_per_s")}
    return path.read_bytes()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--checkpoint-every", type=int, default=50_000)
    parser.add_argument("--kills", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0, help="the run's seed and the kill points'")
    parser.add_argument("--work", default="runs/soak-resume", help="folder for the two runs")
    parser.add_argument("--out", default=None, help="Markdown report")
    args = parser.parse_args()
    work = Path(args.work)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    straight, broken = work / "straight", work / "broken"
    common = ["--env", "doorkey", "--steps", str(args.steps), "--seed", str(args.seed)]
    common += ["--checkpoint-every", str(args.checkpoint_every), "--no-progress"]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    log = (work / "log.txt").open("w")

    git = ["git", "rev-parse", "--short", "HEAD"]  # the code the runs start with
    commit = subprocess.run(git, capture_output=True, text=True, check=False).stdout.strip()
    t0 = time.time()
    reference = subprocess.Popen(
        tlac("train", *common, "--out", str(straight)), env=env, stdout=log, stderr=log
    )

    # kill points: after the first checkpoint, at least two checkpoints apart
    rng = random.Random(args.seed)
    span = args.steps - 2 * args.kills * args.checkpoint_every
    gaps = sorted(rng.sample(range(span), args.kills))
    targets = [
        args.checkpoint_every + g + 2 * i * args.checkpoint_every for i, g in enumerate(gaps)
    ]
    kills: list[tuple[int, int, str]] = []  # (target, last episode step seen, how resumed)
    command = tlac("train", *common, "--out", str(broken))
    for i, target in enumerate(targets):
        proc = subprocess.Popen(command, env=env, stdout=log, stderr=log)
        while last_step(broken / "episodes.csv") < target and proc.poll() is None:
            time.sleep(0.05)
        if proc.poll() is not None:
            print(f"the run ended before step {target}; rc {proc.returncode}", file=sys.stderr)
            return 1
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        how = "tlac train --resume" if i % 2 == 0 else "the same tlac train again"
        kills.append((target, last_step(broken / "episodes.csv"), how))
        print(f"killed at step {kills[-1][1]} (target {target}); continuing with {how}", flush=True)
        if i % 2 == 0:
            command = tlac("train", "--resume", str(broken), "--no-progress")
            command += ["--checkpoint-every", str(args.checkpoint_every)]
        else:
            command = tlac("train", *common, "--out", str(broken))
    final = subprocess.run(command, env=env, stdout=log, stderr=log, check=False)
    reference.wait()
    wall = time.time() - t0
    if final.returncode or reference.returncode:
        print(f"a run failed (see {work / 'log.txt'})", file=sys.stderr)
        return 1

    names = sorted(p.name for p in straight.iterdir() if p.is_file() and p.name != ".run.lock")
    rows, same = [], True
    for name in names:
        ok = (broken / name).exists() and comparable(broken / name) == comparable(straight / name)
        same &= ok
        digest = hashlib.sha256((straight / name).read_bytes()).hexdigest()[:16]
        exact = (broken / name).exists() and (broken / name).read_bytes() == (
            straight / name
        ).read_bytes()
        rows.append(
            f"| {name} | {'same' if ok else 'DIFFERENT'} | {'yes' if exact else 'no'} | {digest} |"
        )
    extra = sorted({p.name for p in broken.iterdir()} - {p.name for p in straight.iterdir()})
    same &= not extra
    result = json.loads((straight / "result.json").read_text())
    report = [
        f"# Exact resume soak: {args.steps:,} DoorKey steps, {args.kills} kill -9 / resume cycles",
        "",
        "```",
        "python " + " ".join(sys.argv),
        "```",
        "",
        f"Commit {commit or '?'}; TL-AC default preset and teachers, seed {args.seed}, checkpoints every "
        f"{args.checkpoint_every:,} steps; wall time {wall / 60:.1f} min (both runs side by side); "
        f"final student alone {result.get('final_eval_mean')}.",
        "",
        "| kill | target step | last episode row at the kill | continued with |",
        "|---|---|---|---|",
        *[f"| {i + 1} | {t:,} | {s:,} | {h} |" for i, (t, s, h) in enumerate(kills)],
        "",
        f"Files of the resumed run against the uninterrupted one (wall-clock fields aside: {WALL_CLOCK}):",
        "",
        "| file | same | byte-identical as a whole | sha256 (uninterrupted, first 16) |",
        "|---|---|---|---|",
        *rows,
        "",
        f"Files only in the resumed run: {', '.join(extra) or 'none'}.",
        "",
        f"**Verdict: {'byte-identical except the wall-clock fields' if same else 'DIFFERENT'}.**",
    ]
    text = "\n".join(report) + "\n"
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(text)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
