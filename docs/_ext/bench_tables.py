"""Sphinx extension: render the committed benchmark run into tables at build time.

A page writes, in MyST::

    ```{bench-table} scaling
    ```

and gets the tables of that part of the run in ``bench_json`` (``conf.py``; default ``bench/bench.json`` beside
``conf.py``), made by :mod:`bench_render` (pure Python, tested without Sphinx). A part the run lacks renders as a
"not measured" note, so an older or partial JSON still builds; a file that is not JSON fails the build.
"""

from __future__ import annotations

import json
from pathlib import Path

from bench_render import PARTS, Table, render
from docutils import nodes
from sphinx.util.docutils import SphinxDirective


def table_node(table: Table) -> nodes.table:
    """A docutils table (built as nodes: the page's parser, MyST or reST, does not matter)."""
    node = nodes.table(classes=["bench-table"])
    group = nodes.tgroup(cols=len(table.header))
    node += group
    group.extend(nodes.colspec(colwidth=1) for _ in table.header)

    def row_node(cells):
        row = nodes.row()
        for text in cells:
            row += nodes.entry("", nodes.paragraph(text=text))
        return row

    head, body = nodes.thead(), nodes.tbody()
    head += row_node(table.header)
    body.extend(row_node(r) for r in table.rows)
    group += head
    group += body
    return node


def note_node(text: str) -> nodes.paragraph:
    """The "not measured" note, its first words emphasised."""
    lead, _, rest = text.partition(" (")
    node = nodes.paragraph()
    node += nodes.emphasis(text=lead)
    if rest:
        node += nodes.Text(" (" + rest)
    return node


class BenchTable(SphinxDirective):
    """``bench-table PART``: the table(s) of one part of the committed benchmark run."""

    required_arguments = 1
    has_content = False

    def run(self):
        """The nodes of the part's tables, or of its "not measured" note."""
        part = self.arguments[0]
        if part not in PARTS:
            raise self.error(f"bench-table: unknown part {part!r}; choose one of {', '.join(PARTS)}")
        path = Path(self.env.srcdir) / self.config.bench_json
        self.env.note_dependency(str(path))
        doc = None
        if path.is_file():
            try:
                doc = json.loads(path.read_text())
            except json.JSONDecodeError as exc:
                raise self.error(f"bench-table: {path} is not JSON ({exc})") from exc
        return [table_node(item) if isinstance(item, Table) else note_node(item) for item in render(doc, part)]


def setup(app):
    """Register the ``bench_json`` setting and the ``bench-table`` directive."""
    app.add_config_value("bench_json", "bench/bench.json", "env")
    app.add_directive("bench-table", BenchTable)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
