"""MkDocs hook: render the doctests in rrls's docstrings as code.

rrls's docstrings hold bare doctests (``>>> ...`` then the expected output), which pytest runs
(``--doctest-modules``). Markdown would read them as paragraphs, and an output line such as
``[0.8, 0.8, 0.8]`` as a broken cross-reference (an error under ``mkdocs build --strict``).
This hook fences each doctest block as ``pycon`` code before Markdown sees it, so the
docstrings stay plain doctests.
"""

from __future__ import annotations

import re

from markdown import Extension, Markdown
from markdown.preprocessors import Preprocessor

PROMPT = re.compile(r"^(\s*)>>>( |$)")
FENCE = re.compile(r"^\s*(```|~~~)")


def fence_doctests(lines: list[str]) -> list[str]:
    """Wrap each doctest block (prompts and their output, up to a blank line) in a fence."""
    out: list[str] = []
    in_fence = False
    block_indent: str | None = None
    for line in lines:
        if block_indent is not None:
            if line.strip() and (line.startswith(block_indent) or not block_indent):
                out.append(line)
                continue
            out.append(f"{block_indent}```")
            block_indent = None
        if FENCE.match(line):
            in_fence = not in_fence
        elif not in_fence and (match := PROMPT.match(line)):
            block_indent = match.group(1)
            out.append(f"{block_indent}```pycon")
        out.append(line)
    if block_indent is not None:
        out.append(f"{block_indent}```")
    return out


class DoctestFences(Preprocessor):
    """Runs before the fenced-code preprocessors, which then render the new fences."""

    def run(self, lines: list[str]) -> list[str]:
        return fence_doctests(lines)


class DoctestFencesExtension(Extension):
    def extendMarkdown(self, md: Markdown) -> None:  # Markdown's API name
        md.preprocessors.register(DoctestFences(md), "rrls_doctest_fences", 40)


def on_config(config):  # MkDocs hook signature
    """Add the extension to the site's and mkdocstrings' Markdown (they share the list)."""
    config.markdown_extensions.append(DoctestFencesExtension())
    return config
