"""The site's navigation from ``docs/index.md`` itself: its links to pages, in their order, become hidden toctrees
appended to the page as Sphinx reads it (the file stays plain Markdown on GitHub). A numbered list is the user
guide, any other list of links the references; then the API and command-line references, the notebooks, the
benchmark report and the README. A page of the site that no toctree names fails the build (-W)."""
from __future__ import annotations

import re

ROOT_DOC = "docs/index"
LINK = re.compile(r"^\s*(?P<numbered>\d+\.|[-*])\s+\[[^]]*\]\((?P<page>[\w-]+)\.md\)", re.MULTILINE)
MORE = {
    "Reference": ["api", "cli"],
    "Notebooks": ["../notebooks/*"],
    "Project": ["../benchmarks/REPORT", "../README"],
}


def toctrees(text: str) -> str:
    """The hidden toctrees (MyST) for the index ``text``: its numbered links, its bulleted links, then ``MORE``."""
    guide = [m["page"] for m in LINK.finditer(text) if m["numbered"][0].isdigit()]
    references = [m["page"] for m in LINK.finditer(text) if not m["numbered"][0].isdigit()]
    out = []
    for caption, pages in {"User guide": guide, "Pages": references, **MORE}.items():
        glob = ":glob:\n" if any("*" in page for page in pages) else ""
        out.append(f"\n```{{toctree}}\n:hidden:\n:maxdepth: 2\n:caption: {caption}\n{glob}\n" + "\n".join(pages)
                   + "\n```\n")
    return "".join(out)


def _append(app, docname: str, source: list[str]) -> None:
    if docname == ROOT_DOC:
        source[0] += toctrees(source[0])


def setup(app):
    app.connect("source-read", _append)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
