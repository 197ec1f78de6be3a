"""Griffe extension of the API reference (mkdocs.yml): tlac's docstrings are written in
reStructuredText habits, which the reference renders as Markdown. Before rendering, each
docstring gets

* its doctests (``>>>`` lines and their output, up to a blank line) fenced as ``pycon`` code,
  not read as nested block quotes;
* its Sphinx roles (``:class:`~tlac.teachers.base.Teacher```) as code (``Teacher``; the full
  name without ``~``), not as literal ``:class:`` text;
* its literal-block markers (a paragraph ending in ``::``) as one colon.

The source docstrings are unchanged (``python -m doctest`` and the tests read them as they are).
"""

from __future__ import annotations

import re
from typing import Any

from griffe import Extension, Object

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj):`(~?)\.?([^`]+)`")
DOCTEST = re.compile(r"^(\s*)>>>( |$)")


def _role(match: re.Match[str]) -> str:
    tilde, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if tilde else target}`"


def _fence_doctests(lines: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(lines):
        start = DOCTEST.match(lines[i])
        if start is None:
            out.append(lines[i])
            i += 1
            continue
        indent = start.group(1)
        if out and out[-1].strip():
            out.append("")
        out.append(f"{indent}```pycon")
        while i < len(lines) and lines[i].strip():
            out.append(lines[i])
            i += 1
        out += [f"{indent}```", ""]
    return out


def markdown_docstring(text: str) -> str:
    """``text`` (a docstring) with its doctests fenced, its roles as code, ``::`` as ``:``.

    >>> markdown_docstring("See :class:`~a.B` and :func:`a.f`::").splitlines()
    ['See `B` and `a.f`:']
    >>> markdown_docstring("Text\\n>>> 1 + 1\\n2").splitlines()
    ['Text', '', '```pycon', '>>> 1 + 1', '2', '```']
    """
    text = ROLE.sub(_role, text)
    text = re.sub(r"(\S)::$", r"\1:", text, flags=re.MULTILINE)
    return "\n".join(_fence_doctests(text.split("\n")))


class ReSTDocstrings(Extension):
    """Rewrites every loaded object's docstring with :func:`markdown_docstring`."""

    def on_object(self, *, obj: Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown_docstring(obj.docstring.value)
