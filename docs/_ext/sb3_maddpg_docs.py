"""Small Sphinx helpers for the sb3-maddpg docs (no extra dependency).

- ``.. markdown-include:: ../CHANGELOG.md``: renders a simple Markdown file (headings, paragraphs,
  bullet lists, inline code, bold, links) as reStructuredText, so the changelog has one source; where the file is
  missing, the directive's content (a note on a page not generated yet), else a warning.
- ``.. include-if-exists:: path``: includes a reStructuredText file when it exists at build time and
  otherwise renders the directive's content (a fallback note), so generated results can be linked
  before they are produced without breaking a ``-W`` build.
- ``.. example-scripts:: dir``: every example script in full, with a summary table.
- ``.. argument-ranges:: module.Constructor module.RANGES``: a table of each numeric argument of the constructor that
  the ranges declare, its valid range, its default and what it is, drawn from the code
  (:mod:`sb3_maddpg.common.argument_ranges`) so the docs cannot disagree with the checks.
- ``.. results-directory:: path``: shows the Markdown tables and the figures of a report directory
  written by ``sb3-maddpg report``, or the directive's content when there is none.
"""

import ast
import importlib
import inspect
import re
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

# Underline characters for Markdown heading levels 2, 3, 4 (level 1 is the page's own title).
_UNDERLINES = {2: "-", 3: "~", 4: "^"}


def _inline(text: str) -> str:
    """Convert Markdown inline markup (code, links) to reStructuredText."""
    parts = re.split(r"(`[^`]+`)", text)
    out = ""
    for index, part in enumerate(parts):
        if index % 2 == 1:  # a code span
            literal = f"``{part[1:-1]}``"
            # reST inline markup must be delimited by spaces or punctuation: escape the joins Markdown allows.
            if out and out[-1].isalnum():
                literal = "\\ " + literal
            following = parts[index + 1] if index + 1 < len(parts) else ""
            if following[:1].isalnum():
                literal += "\\ "
            out += literal
        else:
            # Lone asterisks (e.g. "p < .05 **") or a word ending in ``_`` would be reST markup: escape them.
            part = re.sub(r"(?<![\w*])(\*+)(?![\w*])", lambda match: "\\*" * len(match.group(1)), part)
            part = re.sub(r"(?<=\w)_(?=\s|$|[.,;:)])", r"\\_", part)
            out += re.sub(r"\[([^\]]+)\]\(([^)]+)\)", r"`\1 <\2>`__", part)
    return out


def markdown_to_rst(markdown: str) -> list[str]:
    """
    Convert the Markdown subset used by the changelog to reStructuredText lines.

    :param markdown: The Markdown text.
    :return: reStructuredText lines; the level-1 heading is dropped (the page has its own title).
    """
    lines: list[str] = []
    in_fence = False
    table: list[list[str]] = []
    for raw in [*markdown.splitlines(), ""]:
        line = raw.rstrip()
        if line.lstrip().startswith("|") and not in_fence:
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if not all(re.fullmatch(r":?-{3,}:?", cell) for cell in cells):
                table.append(cells)
            continue
        if table:
            lines += _list_table(table)
            table = []
        fence = re.match(r"^\s*```\s*(\w*)", line)
        if fence:
            in_fence = not in_fence
            lines += ["", f".. code-block:: {fence.group(1) or 'text'}", ""] if in_fence else [""]
            continue
        if in_fence:
            lines.append("   " + line)
            continue
        heading = re.match(r"^(#+)\s+(.*)$", line)
        if heading:
            level = len(heading.group(1))
            if level == 1:
                continue
            title = _inline(heading.group(2))
            lines += ["", title, _UNDERLINES.get(level, "^") * max(len(title), 3), ""]
        elif re.match(r"^\s*[-*]\s+", line):
            indent = len(line) - len(line.lstrip())
            lines.append(" " * indent + "- " + _inline(re.sub(r"^\s*[-*]\s+", "", line)))
        elif line.startswith("  ") and lines and lines[-1].lstrip().startswith("- "):
            lines[-1] += " " + _inline(line.strip())
        elif line.startswith("  ") and lines and lines[-1] and not lines[-1].startswith(" ") and line.strip():
            lines.append(_inline(line))
        else:
            lines.append(_inline(line))
    return lines


def _list_table(rows: list[list[str]]) -> list[str]:
    """A Markdown pipe table (first row: header) as a reST ``list-table``."""
    width = max(len(row) for row in rows)
    out = ["", ".. list-table::", "   :header-rows: 1", ""]
    for row in rows:
        cells = [*row, *[""] * (width - len(row))]
        out.append(f"   * - {_inline(cells[0]) or ' '}")
        out += [f"     - {_inline(cell) or ' '}" for cell in cells[1:]]
    return [*out, ""]


class MarkdownInclude(SphinxDirective):
    """Render a simple Markdown file as reStructuredText; where it is missing, the directive's content (a note on a
    page not yet generated), or a warning when there is none."""

    required_arguments = 1
    has_content = True

    def run(self) -> list[nodes.Node]:
        _, path = self.env.relfn2path(self.arguments[0])
        self.env.note_dependency(path)  # a missing file counts as changed: the page is read again once it is there
        if Path(path).is_file():
            lines = StringList(markdown_to_rst(Path(path).read_text(encoding="utf-8")), source=path)
        elif self.content:
            lines = self.content
        else:
            return [self.state.document.reporter.warning(f"markdown-include: no file {path}", line=self.lineno)]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, lines, container)
        return container.children


class IncludeIfExists(SphinxDirective):
    """Include a reStructuredText file if it exists, else render the directive's content."""

    required_arguments = 1
    has_content = True
    option_spec = {"literal": directives.flag}

    def run(self) -> list[nodes.Node]:
        _, path = self.env.relfn2path(self.arguments[0])
        source = Path(path)
        if source.is_file():
            self.env.note_dependency(path)
            text = source.read_text(encoding="utf-8")
            if "literal" in self.options:
                block = nodes.literal_block(text, text)
                return [block]
            lines = StringList(text.splitlines(), source=str(source))
        else:
            lines = self.content
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, lines, container)
        return container.children


class ResultsDirectory(SphinxDirective):
    """
    Show a results directory written by ``sb3-maddpg report`` (or a copy of it), if it exists: its
    ``index.rst`` or ``results.rst`` if it has one; else ``README.md`` or ``description.md`` first, then
    every ``table_*.md`` each followed by its ``aggregates_*.md`` and ``claims_*.md``, then ``cost.md``, then every
    figure (``*.svg``, ``*.png``).
    Otherwise render the directive's content.
    """

    required_arguments = 1
    has_content = True

    def run(self) -> list[nodes.Node]:
        rel_dir, abs_dir = self.env.relfn2path(self.arguments[0])
        directory = Path(abs_dir)
        # Re-read this page when the directory appears or its files change (a missing one counts as changed).
        self.env.note_dependency(abs_dir)
        for name in ("index.rst", "results.rst"):
            if (directory / name).is_file():  # a hand-written page of the results takes precedence
                self.env.note_dependency(str(directory / name))
                text = (directory / name).read_text(encoding="utf-8")
                return self._parse(StringList(text.splitlines(), source=str(directory / name)))
        texts = [directory / name for name in ("README.md", "description.md") if (directory / name).is_file()]
        for table in sorted(directory.glob("table_*.md")) if directory.is_dir() else []:
            companions = [table.with_name(table.name.replace("table_", prefix, 1)) for prefix in ("aggregates_", "claims_")]
            texts += [table, *(path for path in companions if path.is_file())]
        if (directory / "cost.md").is_file():
            texts.append(directory / "cost.md")
        figures = [*directory.glob("*.svg"), *directory.glob("*.png")] if directory.is_dir() else []
        # Learning curves before boxplots, as in the paper's figures; then by name.
        figures.sort(key=lambda path: (not path.name.startswith("learning_curves"), path.name))
        if not texts and not figures:
            lines = self.content
        else:
            rst: list[str] = []
            for path in texts:
                self.env.note_dependency(str(path))
                rst += [*markdown_to_rst(path.read_text(encoding="utf-8")), ""]
            for path in figures:
                alt = path.stem.replace("_", " ")
                rst += [f".. image:: /{rel_dir}/{path.name}", f"   :alt: {alt}", "   :width: 85%", ""]
            lines = StringList(rst, source=str(directory))
        return self._parse(lines)

    def _parse(self, lines: StringList) -> list[nodes.Node]:
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, lines, container)
        return container.children


class ExampleScripts(SphinxDirective):
    """
    Every ``*.py`` in a directory, in full: a summary table (script, first docstring line), then one
    section per script with its source. Scripts named in ``:order:`` come first, the others after
    in alphabetical order, so a new example is documented as soon as it exists.
    """

    required_arguments = 1
    has_content = False
    option_spec = {"order": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        rel_dir, abs_dir = self.env.relfn2path(self.arguments[0])
        directory = Path(abs_dir)
        self.env.note_dependency(abs_dir)  # a new script changes the directory's modification time
        order = self.options.get("order", "").split()
        rank = {name: index for index, name in enumerate(order)}
        scripts = sorted(directory.glob("*.py"), key=lambda path: (rank.get(path.name, len(order)), path.name))
        summaries = {}
        for path in scripts:
            self.env.note_dependency(str(path))
            docstring = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or path.stem
            summaries[path.name] = docstring.strip().splitlines()[0].rstrip(".")
        if not scripts:
            return [nodes.paragraph(text=f"No example scripts found in {self.arguments[0]}.")]
        rst = [".. list-table::", "   :header-rows: 1", "   :widths: 30 70", "", "   * - script", "     - what it shows"]
        for name, summary in summaries.items():
            rst += [f"   * - :ref:`{name} <example-{Path(name).stem}>`", f"     - {summary}"]
        rst.append("")
        for path in scripts:
            title = f"``{path.name}``"
            rst += [f".. _example-{path.stem}:", "", title, "-" * len(title), "", f"{summaries[path.name]}.", ""]
            rst += [f".. literalinclude:: /{rel_dir}/{path.name}", "   :language: python", ""]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(rst, source=str(directory)), container)
        return container.children


def _import_path(path: str) -> Any:
    """:return: The object at a dotted path (``package.module.Name``)."""
    module, _, name = path.rpartition(".")
    return getattr(importlib.import_module(module), name)


class ArgumentRanges(SphinxDirective):
    """A table of a constructor's numeric arguments: valid range, default, meaning (from the declared ranges)."""

    required_arguments = 2
    has_content = False

    def run(self) -> list[nodes.Node]:
        constructor, ranges = (_import_path(path) for path in self.arguments)
        parameters = inspect.signature(constructor).parameters
        rows = [".. list-table::", "   :header-rows: 1", "   :widths: 18 30 12 40", ""]
        rows += ["   * - argument", "     - valid range", "     - default", "     - what it is"]
        for name, valid in ranges.items():
            default = parameters[name].default if name in parameters else inspect.Parameter.empty
            shown = "(required)" if default is inspect.Parameter.empty else f"``{default!r}``"
            rows += [f"   * - ``{name}``", f"     - {valid.describe()}", f"     - {shown}", f"     - {valid.meaning}"]
        container = nodes.section()
        container.document = self.state.document
        nested_parse_with_titles(self.state, StringList(rows, source="argument-ranges"), container)
        return container.children


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("argument-ranges", ArgumentRanges)
    app.add_directive("markdown-include", MarkdownInclude)
    app.add_directive("include-if-exists", IncludeIfExists)
    app.add_directive("results-directory", ResultsDirectory)
    app.add_directive("example-scripts", ExampleScripts)
    return {"version": "0.1", "parallel_read_safe": True, "parallel_write_safe": True}
