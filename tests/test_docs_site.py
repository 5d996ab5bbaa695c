"""The documentation site's check of the public names (docs/_ext/flexmor_docs.py), without Sphinx.

``make docs`` runs the same check while it builds (a warning, and with ``-W`` a failed build); here it runs
with the tests: every name of ``flexmor.__all__`` is listed in docs/api.rst and has a docstring.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import flexmor

ROOT = Path(__file__).resolve().parents[1]


def site_extension():
    spec = importlib.util.spec_from_file_location("flexmor_docs", ROOT / "docs" / "_ext" / "flexmor_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_public_name_is_in_the_api_reference_with_a_docstring():
    assert site_extension().missing_public_names() == []


def test_the_check_finds_an_unlisted_name_and_a_missing_docstring(monkeypatch):
    ext = site_extension()
    api = (ROOT / "docs" / "api.rst").read_text(encoding="utf-8")
    assert "   make_ports\n" in api
    found = ext.missing_public_names(api.replace("   make_ports\n", "", 1))
    assert found == ["flexmor.make_ports is public (flexmor.__all__) but not listed in docs/api.rst"]
    monkeypatch.setattr(flexmor.read, "__doc__", None)
    assert ext.missing_public_names(api) == ["flexmor.read is public (flexmor.__all__) but has no docstring"]


def test_the_repository_pages_the_docs_link_to_are_on_the_site():
    ext = site_extension()
    for target, page in ext.REPOSITORY_PAGES.items():
        assert (ROOT / f"{target}.md").is_file(), target
        assert (ROOT / "docs" / f"{page}.md").is_file(), page
    assert ext._site_page("../README.md", "tutorial") == "guide/getting-started"
    assert ext._site_page("../../README.md#tour", "guide/example-data") == "guide/getting-started"
    assert ext._site_page("examples/README.md", "guide/python") == "guide/examples"
    assert ext._site_page("tutorial.md", "index") is None
