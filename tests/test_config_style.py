"""One config style (issue 12, item 5): TL-AC's, DQN-TLQL's and AC-Teach's settings and the
experiment schema are frozen dataclasses with a docstring under every field, checked when they
are made, and a bad value raises one ConfigError naming the field, the value and what was
expected (tlac.validation)."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import textwrap

import pytest

from tlac.baselines.ac_teach import ACTeachConfig
from tlac.baselines.dqn_tlql import DQNTLQLConfig
from tlac.errors import ConfigError
from tlac.experiments.config import (
    AlgorithmEntry,
    EvalSchedule,
    ExperimentConfig,
    MetricSettings,
    TeacherSet,
)
from tlac.two_level.config import TLACConfig

CONFIGS = [
    TLACConfig,
    DQNTLQLConfig,
    ACTeachConfig,
    EvalSchedule,
    MetricSettings,
    TeacherSet,
    AlgorithmEntry,
    ExperimentConfig,
]


def _undocumented(cls: type) -> list[str]:
    """The fields of ``cls`` without a string literal right below them in its source."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body  # type: ignore[attr-defined]
    missing = []
    for node, after in zip(body, [*body[1:], None], strict=True):
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            documented = (
                isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)
                and isinstance(after.value.value, str)
            )
            if not documented:
                missing.append(node.target.id)
    return missing


@pytest.mark.parametrize("cls", CONFIGS, ids=[c.__name__ for c in CONFIGS])
def test_frozen_dataclass_with_a_docstring_per_field(cls: type) -> None:
    assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen  # type: ignore[attr-defined]
    assert _undocumented(cls) == []


@pytest.mark.parametrize(
    ("make", "fragments"),
    [
        (lambda: TLACConfig(gamma=2.0), ["TL-AC setting gamma", "in [0, 1]", "got 2.0"]),
        (lambda: TLACConfig(n_steps=0), ["TL-AC setting n_steps", "positive integer", "got 0"]),
        (lambda: TLACConfig(kl_rows="blind"), ["kl_rows", "'blind'", "agent, all, high"]),
        (lambda: DQNTLQLConfig(tau=0.0), ["dqn-tlql setting tau", "in (0, 1]", "got 0.0"]),
        (lambda: DQNTLQLConfig(learning_starts=-1), ["learning_starts", ">= 0", "got -1"]),
        (lambda: ACTeachConfig(obs_clip=-1.0), ["ac-teach setting obs_clip", "> 0", "got -1.0"]),
        (lambda: ACTeachConfig(switch_sign="up"), ["switch_sign", "'up'", "paper, code"]),
        (lambda: EvalSchedule(episodes=-1), ["field 'episodes'", ">= 0", "got -1"]),
        (lambda: MetricSettings(curve_points=1), ["field 'curve_points'", ">= 2", "got 1"]),
    ],
)
def test_a_bad_value_names_the_field_the_value_and_the_expectation(make, fragments) -> None:
    with pytest.raises(ConfigError) as info:
        make()
    for fragment in fragments:
        assert fragment in str(info.value)


def test_configs_cannot_be_changed_after_they_are_checked() -> None:
    cfg = TLACConfig(variant="paper")
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.gamma = 2.0  # type: ignore[misc]
    assert cfg.kl_rows == "all"  # the variant's default, filled in while it was made
