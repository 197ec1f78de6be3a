"""Every ```python block of README.md and docs/ runs (issue 11), with its step counts made
small: a snippet that a user copies must not fail on a name it never defined."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHRINK = [
    (re.compile(r"\.learn\(\s*[\d_]+"), ".learn(256"),  # training budgets
    (re.compile(r"\b(episodes|eval_freq|save_freq)=[\d_]+"), r"\1=2"),
    (re.compile(r"n_eval_episodes=[\d_]+"), "n_eval_episodes=1"),
    (re.compile(r"\"configs/"), f'"{ROOT / "configs"}/'),  # the repository's configs
]


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
    monkeypatch.chdir(tmp_path)  # files the snippet writes land here
    exec(compile(code, where, "exec"), {"__name__": "__snippet__"})  # noqa: S102
