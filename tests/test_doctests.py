"""Every docstring example in the package runs and prints what it shows (issue 12: they were
not run, and some had drifted from the code)."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import tlac

MODULES = sorted(
    m.name
    for m in pkgutil.walk_packages(tlac.__path__, prefix="tlac.")
    if not m.name.endswith(".__main__")
)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
