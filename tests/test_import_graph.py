"""The package's import graph, read with the standard library's ast: no circles (function-local
imports included: a lazy import that only hides a circle is a circle), and no module imports
a layer above its own (docs/architecture.md, "Layers")."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src"

LAYERS: list[tuple[str, ...]] = [
    ("tlac.errors", "tlac.argtypes", "tlac.presets", "tlac.validation", "tlac.memory"),
    # generic: base, wrappers, the shipped-policy teachers (sac, ppo), a person's answers
    ("tlac.teachers",),
    ("tlac.recording",),
    ("tlac.domains", "tlac.gym_ids"),
    ("tlac.algorithms", "tlac.selectors"),  # the registry, the parts algorithms share
    ("tlac.two_level", "tlac.baselines"),  # TL-AC; the baselines it is compared with
    ("tlac.evaluation", "tlac.run", "tlac.teacher_training", "tlac.human"),
    ("tlac.experiments",),
    ("tlac.cli", "tlac.__main__"),
]
"""Lowest first. A module belongs to the layer of the longest prefix listed; ``tlac`` itself
(the package's __init__: the public names) may import anything."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path, name: str) -> set[str]:
    """Every tlac module ``path`` imports, at any depth of its code."""
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.add(base)
            found |= {f"{base}.{a.name}" for a in node.names}
    return {m for m in found if m == "tlac" or m.startswith("tlac.")}


def graph() -> dict[str, set[str]]:
    modules = {module_name(p): p for p in SRC.joinpath("tlac").rglob("*.py")}
    edges: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = {t for t in imports_of(path, name) if t in modules}
        edges[name] = {t for t in targets if t != name and not name.startswith(t + ".")}
    return edges


def layer_of(module: str) -> int | None:
    best, level = -1, None
    for i, layer in enumerate(LAYERS):
        for prefix in layer:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, level = len(prefix), i
    return level


def test_no_import_circles() -> None:
    edges = graph()
    # a package's __init__ importing its own submodules is how packages work: not a circle
    edges = {m: {t for t in ts if not t.startswith(m + ".")} for m, ts in edges.items()}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(edges.get(m, ())):
            if state.get(t) == 1:
                cycle = [*stack[stack.index(t) :], t]
                pytest.fail("import circle: " + " -> ".join(cycle))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)


def test_no_module_imports_a_layer_above_its_own() -> None:
    wrong = []
    for module, targets in graph().items():
        own = layer_of(module)
        if module == "tlac" or own is None:
            continue
        for target in targets:
            other = layer_of(target)
            if other is not None and other > own and target != "tlac":
                wrong.append(f"{module} (layer {own}) imports {target} (layer {other})")
    assert not wrong, "\n".join(sorted(wrong))


def test_no_layer_names_a_part_of_another_layers_package() -> None:
    """A layer holds whole packages and modules: none is placed inside another layer's
    package, where it would be an exception to that package's layer."""
    prefixes = [p for layer in LAYERS for p in layer]
    nested = [f"{a} inside {b}" for a in prefixes for b in prefixes if a.startswith(b + ".")]
    assert not nested, nested


def test_every_module_has_a_layer() -> None:
    unplaced = [m for m in graph() if m != "tlac" and layer_of(m) is None]
    assert not unplaced, unplaced
