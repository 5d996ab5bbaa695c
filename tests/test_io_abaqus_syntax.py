"""The line syntax of Abaqus-style decks (flexmor.io._abaqus_syntax), as both deck readers use it."""

from __future__ import annotations

import numpy as np
import pytest

from flexmor.errors import ReadError
from flexmor.io._abaqus_syntax import Data, Keyword, keyword_options, walk
from flexmor.io.abaqus import read_deck
from flexmor.io.calculix import read_inp


def _deck(tmp_path):
    (tmp_path / "more.inp").write_text("5, 1.0, 1.0, 0.0\n*NODE, NSET=MORE\n3, 2.0, 0.0, 0.0\n  ** indented comment\n"
                                       "4, 3.0, 0.0, 0.0\n")
    main = tmp_path / "main.inp"
    main.write_text("** head\n*Node, nset=Base\n1, 0.0, 0.0, 0.0\n\n2, 1.0, 0.0, 0.0\n"
                    "*INCLUDE, INPUT=\"more.inp\"\n6, 9.0, 9.0, 9.0\n*nset, NSET=ALL, GENERATE\n1, 4\n")
    return main


def test_walk_reads_keywords_data_and_includes_in_file_order(tmp_path):
    main = _deck(tmp_path)
    items = list(walk(main))
    kinds = [(type(i).__name__, i.name if isinstance(i, Keyword) else len(i.lines)) for i in items]
    assert kinds == [("Keyword", "NODE"), ("Data", 2), ("Keyword", "INCLUDE"), ("Data", 1), ("Keyword", "NODE"),
                     ("Data", 2), ("Data", 1), ("Keyword", "NSET"), ("Data", 1)]
    node, first = items[0], items[1]
    assert node.options == {"NSET": "Base"} and node.path == main and node.line == 2
    assert first.lines == ["1, 0.0, 0.0, 0.0", "2, 1.0, 0.0, 0.0"] and first.linenos == [3, 5]
    included = items[3]  # lines before the first keyword of an included file belong to no keyword
    assert included.keyword is None and included.path == tmp_path / "more.inp" and included.linenos == [1]
    assert items[5].keyword is items[4] and items[5].linenos == [3, 5]  # the comment is skipped
    after = items[6]  # lines after *INCLUDE belong to no keyword either
    assert isinstance(after, Data) and after.keyword is None and after.path == main and after.linenos == [7]
    assert items[7].options == {"NSET": "ALL", "GENERATE": ""}


def test_keyword_names_are_upper_case_with_single_blanks():
    assert keyword_options("*end   Part") == ("END PART", {})
    assert keyword_options('*Solid Section, elset=E1, material="Steel"') == (
        "SOLID SECTION", {"ELSET": "E1", "MATERIAL": "Steel"})


def test_both_readers_read_the_same_deck_alike(tmp_path):
    main = _deck(tmp_path)
    ids, xyz, sets = read_inp(main)
    deck = read_deck(main)
    assert ids.tolist() == [1, 2, 3, 4] and deck.node_ids.tolist() == [1, 2, 3, 4]
    np.testing.assert_array_equal(deck.xyz, xyz)
    assert xyz[3].tolist() == [3.0, 0.0, 0.0]  # 5 and 6, outside any keyword, are no nodes
    for name, members in {"BASE": [1, 2], "MORE": [3, 4], "ALL": [1, 2, 3, 4]}.items():
        assert sets[name].tolist() == members and deck.node_sets[name].tolist() == members


@pytest.mark.parametrize("reader", [read_inp, read_deck])
@pytest.mark.parametrize(("include", "message"), [
    ("*INCLUDE", r"main\.inp:2: \*INCLUDE without INPUT=file"),
    ("*INCLUDE, INPUT=gone.inp", r"main\.inp:2: included file gone\.inp not found"),
    ("*INCLUDE, INPUT=main.inp", r"main\.inp:2: \*INCLUDE nested deeper than 10 levels"),
])
def test_both_readers_refuse_a_bad_include_naming_file_and_line(tmp_path, reader, include, message):
    main = tmp_path / "main.inp"
    main.write_text(f"*NODE\n{include}\n1, 0.0, 0.0, 0.0\n")
    with pytest.raises(ReadError, match=message):
        reader(main)
