"""MkDocs hooks (mkdocs.yml, ``hooks:``): the README as the home page, and links that leave
``docs/``.

* ``docs/index.md`` holds ``<!-- include -->`` above a link to ``../README.md``: the hook puts
  the README's text in place of the link, its links made relative to ``docs/index.md`` (the
  README links ``docs/algorithm.md``, the site has it as ``algorithm.md``).
* The pages are written to be read on GitHub too, where they link files of the repository
  outside ``docs/`` (``../results/doorkey-r2/NOTES.md``, ``../examples/my_domain.py``) and
  folders (``docs/baselines``). The site has no copy of them: such a link becomes its text
  (with the path in code when the text is not the path), and a link to a file that does not
  exist is a warning, so ``mkdocs build --strict`` fails on it as on a broken link in ``docs/``.
  An image outside ``docs/`` (a figure of results/) becomes its caption and path in the same way.

Links inside ``docs/`` are left to MkDocs, which checks them (and their anchors) itself.
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.tlac")

INCLUDE = re.compile(r"^<!-- include -->\n\[[^\]]*\]\(([^)\s]+)\)$", re.MULTILINE)
LINK = re.compile(r"(?<!!)\[([^\]\n]+)\]\(([^)\s]+)\)")
IMAGE = re.compile(r"!\[([^\]\n]*)\]\(([^)\s]+)\)")
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
EXTERNAL = re.compile(r"^(?:[a-z][a-z0-9+.-]*:|#|/)", re.IGNORECASE)


def _relink(text: str, base: Path, docs: Path, page_dir: Path, where: str) -> str:
    """``text``'s links written relative to ``base``, made to work from a page in
    ``page_dir``: into ``docs/`` relative to the page, elsewhere as plain text."""

    def one(match: re.Match[str]) -> str:
        label, target = match.groups()
        if EXTERNAL.match(target):
            return match.group(0)
        path, hash_, anchor = target.partition("#")
        resolved = Path(os.path.normpath(base / path))
        if resolved.is_file() and resolved.is_relative_to(docs):
            if base == page_dir:
                return match.group(0)  # MkDocs checks it
            return f"[{label}]({os.path.relpath(resolved, page_dir)}{hash_}{anchor})"
        if not resolved.exists():
            if resolved.is_relative_to(docs) and base == page_dir:
                return match.group(0)  # MkDocs reports it
            log.warning("%s links %r, which does not exist (%s)", where, target, resolved)
            return match.group(0)
        shown = os.path.relpath(resolved, docs.parent)
        return label if label.strip("`") in (path, shown, shown + "/") else f"{label} (`{shown}`)"

    def image(match: re.Match[str]) -> str:
        alt, target = match.groups()
        if EXTERNAL.match(target):
            return match.group(0)
        resolved = Path(os.path.normpath(base / target))
        if resolved.is_file() and resolved.is_relative_to(docs):
            if base == page_dir:
                return match.group(0)  # MkDocs checks it
            return f"![{alt}]({os.path.relpath(resolved, page_dir)})"
        if not resolved.exists():
            log.warning("%s shows %r, which does not exist (%s)", where, target, resolved)
            return match.group(0)
        return f"*{alt}* (`{os.path.relpath(resolved, docs.parent)}`)"  # not in the site

    def both(chunk: str) -> str:
        return LINK.sub(one, IMAGE.sub(image, chunk))

    parts, last = [], 0
    for fence in FENCE.finditer(text):  # code blocks are left as they are
        parts += [both(text[last : fence.start()]), fence.group(0)]
        last = fence.end()
    return "".join([*parts, both(text[last:])])


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    docs = Path(config["docs_dir"]).resolve()
    page_dir = Path(page.file.abs_src_path).resolve().parent
    where = page.file.src_uri

    def include(match: re.Match[str]) -> str:
        path = (page_dir / match.group(1)).resolve()
        return _relink(path.read_text(), path.parent, docs, page_dir, f"{where} ({path.name})")

    markdown = INCLUDE.sub(include, markdown)
    return _relink(markdown, page_dir, docs, page_dir, where)
