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


def _element_deck(tmp_path, etype: str, n: int, rows: list) -> tuple:
    """A deck of two elements of ``etype`` (``n`` nodes each, numbers 1 and 2, nodes 1..n and n+1..2n) whose
    ``*ELEMENT`` data lines are ``rows(number, nodes)`` per element."""
    nodes = [list(range(1, n + 1)), list(range(n + 1, 2 * n + 1))]
    lines = ["*NODE"] + [f"{k}, {k}.0, {k % 3}.0, {k % 5}.0" for k in range(1, 2 * n + 1)]
    lines += [f"*ELEMENT, TYPE={etype}, ELSET=E"]
    for number, ids in zip((1, 2), nodes):
        lines += rows(number, ids)
    path = tmp_path / "e.inp"
    path.write_text("\n".join(lines) + "\n")
    return path, nodes


def _row(values) -> str:
    return ", ".join(str(v) for v in values)


#: How an element of more than 15 nodes is written: a full first line of 16 entries (the number and 15 nodes)
#: continued without a comma (CalculiX reads it so); the first line ending in a comma; the nodes spread
#: over short lines that each end in a comma; all on one line.
LAYOUTS = {
    "full line": lambda number, ids: [_row([number] + ids[:15]), _row(ids[15:])],
    "trailing comma": lambda number, ids: [_row([number] + ids[:15]) + ",", _row(ids[15:])],
    "short lines with commas": lambda number, ids: [_row([number] + ids[:7]) + ",", _row(ids[7:14]) + ",",
                                                    _row(ids[14:])],
    "one line": lambda number, ids: [_row([number] + ids)],
}


def _read_both(path, caplog) -> tuple:
    """The ``*ELEMENT`` rows as the CalculiX reader (mesh cells and element blocks) and the Abaqus reader
    read them: ``(cells, blocks, deck)``; no warning is logged."""
    import logging

    from flexmor.io._abaqus_materials import DeckElements

    cells, elements = [], DeckElements()
    with caplog.at_level(logging.WARNING):
        read_inp(path, cells=cells, elements=elements)
        deck = read_deck(path)
    assert [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING] == []
    return cells, elements.blocks, deck


@pytest.mark.parametrize("etype, n", [("C3D20R", 20), ("C3D20", 20), ("C3D27", 27)])
@pytest.mark.parametrize("layout", LAYOUTS)
def test_element_of_more_than_15_nodes_continues_on_the_next_line(tmp_path, caplog, etype, n, layout):
    path, nodes = _element_deck(tmp_path, etype, n, LAYOUTS[layout])
    cells, blocks, deck = _read_both(path, caplog)
    assert len(cells) == 1 and cells[0][1].tolist() == nodes
    ((block_type, ids, rows),) = blocks
    assert block_type == etype and ids.tolist() == [1, 2] and rows.tolist() == nodes
    assert [(t, e.tolist()) for t, e in deck.elements] == [(etype, nodes[0]), (etype, nodes[1])]
    assert deck.element_labels == [1, 2] and deck.element_sets["E"] == [0, 1]


@pytest.mark.parametrize("etype, n", [("C3D15", 15), ("C3D10", 10), ("C3D8", 8)])
def test_full_line_of_a_complete_element_ends_it(tmp_path, caplog, etype, n):
    """A C3D15 line holds 16 entries (its number and 15 nodes), the most a line holds, and is complete: the next
    line is the next element, not a continuation; so is the line after an element whose line ends in a comma."""
    for rows in (lambda number, ids: [_row([number] + ids)], lambda number, ids: [_row([number] + ids) + ","]):
        path, nodes = _element_deck(tmp_path, etype, n, rows)
        cells, blocks, deck = _read_both(path, caplog)
        assert len(cells) == 1 and cells[0][1].tolist() == nodes
        assert blocks[0][1].tolist() == [1, 2] and blocks[0][2].tolist() == nodes
        assert [(t, e.tolist()) for t, e in deck.elements] == [(etype, nodes[0]), (etype, nodes[1])]


@pytest.mark.parametrize("count", [10, 14])
def test_element_ending_short_of_its_nodes_is_named(tmp_path, caplog, count):
    """A line of fewer than 16 entries without a comma ends its element: a C3D20R element of 10 or 14 nodes and
    the rest on the next line leaves the block out of the mesh, naming the element (the fast and the line-by-line
    parse agree: the total count of numbers, 42, is that of two elements)."""
    import logging

    def rows(number, ids):
        return [_row([number] + ids[:count]), _row(ids[count:])]

    path, _ = _element_deck(tmp_path, "C3D20R", 20, rows)
    cells = []
    with caplog.at_level(logging.WARNING):
        read_inp(path, cells=cells)
    assert cells == []
    assert f"element 1 of type C3D20R has {count} nodes, expected 20" in caplog.text


def test_element_lines_read_at_once_as_line_by_line():
    """The vectorized parse of an ``*ELEMENT`` block joins lines into elements as the line-by-line parse does,
    or leaves the block to it (only for a blank field, or a defect the line-by-line parse names): random
    layouts (line breaks anywhere, commas or none at the breaks, blank fields, blanks) of C3D8, C3D15 and
    C3D20 elements; the plain layouts are read at once."""
    from flexmor.io.calculix.deck import _element_lines, _element_rows

    rng = np.random.default_rng(7)
    at_once = 0
    for trial in range(600):
        nn = (8, 15, 20)[trial % 3]
        plain = trial < 60
        data = []
        for number in range(1, 5):
            values = [str(number)] + [str(v) for v in rng.integers(1, 99, nn)]
            if plain:  # one line, or a full line and the rest (with a comma on odd trials)
                cuts = [16] if nn == 20 else []
            else:
                cuts = sorted(rng.choice(np.arange(1, 1 + nn), rng.integers(0, 3), replace=False).tolist())
            for a, b in zip([0] + cuts, cuts + [1 + nn]):
                sep = ", " if plain else str(rng.choice([",", ", ", " ,", ",\t", ",,", ", ,"],
                                                        p=[.3, .3, .2, .1, .05, .05]))
                line = sep.join(values[a:b])
                if (trial % 2 if plain else rng.random() < (0.7 if b < 1 + nn else 0.1)):
                    line += ","
                data.append(line)
        linenos = list(range(1, len(data) + 1))
        fast = _element_rows(data, 1 + nn)
        slow = _element_lines("e.inp", data, linenos, "T", nn)
        if fast is not None:
            at_once += 1
            assert slow is not None and fast.tolist() == slow.tolist(), data
        elif slow is not None:  # left to the line-by-line parse only for a blank field
            assert any(",," in t.replace(" ", "") for t in data), data
        if plain:
            assert fast is not None and fast.reshape(-1, 1 + nn)[:, 0].tolist() == [1, 2, 3, 4], data
    assert at_once > 120
