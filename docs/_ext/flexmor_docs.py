"""What the flexmor site adds to Sphinx: the check of the public names and the table of the methods.

* ``check_public_names``: every name of ``flexmor.__all__`` is listed in the API reference (docs/api.rst)
  and has a docstring; otherwise a warning, which ``make docs`` (``-W``) turns into a failed build.
  ``missing_public_names`` is the check itself (tests/test_docs_site.py runs it without Sphinx).
* ``.. flexmor-methods::``: the reduction methods as registered (``flexmor.reduction.METHODS``), each with
  its description, what it needs and its options with their defaults and help lines.
* ``link_repository_pages``: the links of the Markdown files to the README and the examples' READMEs
  (files outside docs/) lead to the pages of the site that show them.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
API_PAGE = DOCS / "api.rst"
#: the repository's Markdown files outside docs/ and the pages of the site that include them
REPOSITORY_PAGES = {
    "README": "guide/getting-started",
    "examples/data/README": "guide/example-data",
    "examples/README": "guide/examples",
}
_ENTRY = re.compile(r"^\s+~?(?:flexmor\.)?([A-Za-z_][\w.]*)\s*$")


def listed_names(api_text: str) -> set[str]:
    """The names listed in the ``autosummary`` tables of the API page (``api_text``)."""
    names, inside = set(), False
    for line in api_text.splitlines():
        if line.strip().startswith(".. autosummary::"):
            inside = True
            continue
        if inside:
            if not line.strip() or line.strip().startswith(":"):
                continue
            m = _ENTRY.match(line)
            if m and line.startswith(" "):
                names.add(m.group(1))
            else:
                inside = False
    return names


def missing_public_names(api_text: str | None = None) -> list[str]:
    """What is wrong with the documentation of ``flexmor.__all__``: names not listed, names without docstring."""
    import flexmor

    if api_text is None:
        api_text = API_PAGE.read_text(encoding="utf-8")
    listed = listed_names(api_text)
    found = []
    for name in flexmor.__all__:
        if name == "__version__":
            if ".. data:: __version__" not in api_text:
                found.append("flexmor.__version__ is not described in docs/api.rst ('.. data:: __version__')")
            continue
        if name not in listed:
            found.append(f"flexmor.{name} is public (flexmor.__all__) but not listed in docs/api.rst")
        obj = getattr(flexmor, name)
        if not (obj.__doc__ or "").strip() or (inspect.getdoc(obj) or "").strip() == "":
            found.append(f"flexmor.{name} is public (flexmor.__all__) but has no docstring")
    for name in sorted(listed - set(flexmor.__all__)):
        found.append(f"docs/api.rst lists {name}, which is not in flexmor.__all__")
    return found


def check_public_names(app) -> None:
    from sphinx.util import logging

    logger = logging.getLogger("flexmor_docs")
    for problem in missing_public_names():
        logger.warning(problem, location="api")


def _site_page(target: str, refdoc: str) -> str | None:
    """The page of the site for a link ``target`` (a path, absolute or relative to the repository root or to
    the document ``refdoc``) to one of :data:`REPOSITORY_PAGES`; None for other targets."""
    path = target.split("#", 1)[0]
    path = path[:-3] if path.endswith(".md") else path
    candidates = [Path(path)] if Path(path).is_absolute() else [ROOT / path, (DOCS / refdoc).parent / path]
    for candidate in candidates:
        try:
            key = candidate.resolve().relative_to(ROOT).as_posix()
        except ValueError:
            continue
        if key in REPOSITORY_PAGES:
            return REPOSITORY_PAGES[key]
    return None


def link_repository_pages(app, doctree) -> None:
    from sphinx import addnodes

    for node in doctree.findall(addnodes.pending_xref):
        if node.get("reftype") != "myst":
            continue
        target = node["reftarget"]
        page = _site_page(target, node.get("refdoc", app.env.docname))
        if page is None:
            continue
        anchor = node.get("reftargetid") or (target.split("#", 1)[1] if "#" in target else None)
        node["refdomain"], node["reftarget"], node["reftargetid"] = "doc", page, anchor


def _methods_table():
    from docutils import nodes

    from flexmor.reduction import METHODS

    table = nodes.table(classes=["flexmor-methods"])
    group = nodes.tgroup(cols=3)
    table += group
    for width in (18, 40, 42):
        group += nodes.colspec(colwidth=width)
    head = nodes.thead()
    group += head
    row = nodes.row()
    for title in ("method", "what it builds", "options (default): meaning"):
        row += nodes.entry("", nodes.paragraph(text=title))
    head += row
    body = nodes.tbody()
    group += body
    for name, method in METHODS.items():
        row = nodes.row()
        row += nodes.entry("", nodes.paragraph("", "", nodes.literal(text=name)))
        facts = [method.description + "."]
        facts.append("Built for the inputs (and outputs)." if method.uses_inputs else "Independent of the ports.")
        facts.append("Its accuracy carries over to an assembly (interpolation or exact interface)."
                     if method.survives_coupling else "Its error bound does not carry over to an assembly.")
        row += nodes.entry("", nodes.paragraph(text=" ".join(facts)))
        options = nodes.bullet_list()
        for field in dataclasses.fields(method.options_class) if method.options_class else ():
            default = field.default if field.default is not dataclasses.MISSING else None
            item = nodes.paragraph()
            item += nodes.literal(text=f"{field.name}={default!r}" if default is not None else field.name)
            item += nodes.Text(": " + field.metadata.get("help", ""))
            options += nodes.list_item("", item)
        row += nodes.entry("", options)
        body += row
    return table


def setup(app):
    from sphinx.util.docutils import SphinxDirective

    class MethodsDirective(SphinxDirective):
        """``.. flexmor-methods::``: the table of the registered reduction methods."""

        has_content = False

        def run(self):
            return [_methods_table()]

    app.add_directive("flexmor-methods", MethodsDirective)
    app.connect("builder-inited", check_public_names)
    app.connect("doctree-read", link_repository_pages)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
