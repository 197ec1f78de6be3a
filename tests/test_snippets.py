"""Every ```python block of README.md and docs/ runs (issue 11), with its step counts made
small: a snippet that a user copies must not fail on a name it never defined."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from tlac.two_level import config as tlac_config

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHRINK = [
    (re.compile(r"\.learn\(\s*[\d_]+"), ".learn(256"),  # training budgets
    (re.compile(r"\bepisodes=[\d_]+"), "episodes=2"),
    (re.compile(r"\b(eval_freq|save_freq)=[\d_]+"), r"\1=128"),  # twice in 256 steps
    (re.compile(r"n_eval_episodes=[\d_]+"), "n_eval_episodes=1"),
    (re.compile(r"\"configs/"), f'"{ROOT / "configs"}/'),  # the repository's configs
]


def _small_rollouts(load_preset: Callable[[str, str], dict]) -> Callable[[str, str], dict]:
    """``load_preset`` with 64-step rollouts, 2 epochs of 32-row minibatches in the default preset."""

    def load(name: str, algo: str) -> dict:
        settings = load_preset(name, algo)
        if name == "default" and algo == "tlac":
            settings.update(n_steps=64, batch_size=32, n_epochs=2)
        return settings

    return load


def _snippets() -> list[tuple[str, str]]:
    found = []
    for path in FILES:
        for i, match in enumerate(BLOCK.finditer(path.read_text())):
            found.append((f"{path.relative_to(ROOT)}[{i}]", match.group(1)))
    return found


SNIPPETS = _snippets()


def test_the_docs_have_snippets() -> None:
    assert len(SNIPPETS) >= 8  # README, algorithm, control, experiments, teachers...


@pytest.mark.parametrize(("where", "code"), SNIPPETS, ids=[w for w, _ in SNIPPETS])
def test_snippet_runs(where: str, code: str, tmp_path: Path, monkeypatch) -> None:
    for pattern, replacement in SHRINK:
        code = pattern.sub(replacement, code)
    # and the rollout of a user's environment with the budgets: presets/default.yaml's 2048
    # steps x 10 epochs would outlast every 256-step learn (a CNN snippet took 20 s)
    monkeypatch.setattr(tlac_config, "load_preset", _small_rollouts(tlac_config.load_preset))
    monkeypatch.chdir(tmp_path)  # files the snippet writes land here
    exec(compile(code, where, "exec"), {"__name__": "__snippet__"})  # noqa: S102
