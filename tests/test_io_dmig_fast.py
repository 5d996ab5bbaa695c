"""The vectorized DMIG punch reader gives what the card-by-card reader gives, and leaves it every file it
does not fully understand."""

import numpy as np
import pytest
from helpers import DATA

import flexmor.io.nastran.nastran as nastran
from flexmor.io.nastran.dmig_fast import fast_dmig

PCH = DATA / "nastran" / "pyyeti_matrix_factory.pch"


def _card_by_card(path, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(nastran, "fast_dmig", lambda path: None)
        return nastran.read_dmig(path)


def _same(a, b):
    assert a.keys() == b.keys()
    for name in a:
        assert a[name][0] == b[name][0]
        for x, y in zip(a[name][1:], b[name][1:]):
            np.testing.assert_array_equal(x, y)


def _real_part(tmp_path):
    """The punch file without its complex matrix CMPLX (complex ones go to the card reader)."""
    lines = PCH.read_text().splitlines()
    path = tmp_path / "real.pch"
    path.write_text("\n".join(lines[:lines.index(next(x for x in lines if x.startswith("DMIG    CMPLX")))]) + "\n")
    return path


def test_punch_file_read_alike(tmp_path, monkeypatch):
    assert fast_dmig(PCH) is None  # complex CMPLX inside
    path = _real_part(tmp_path)
    fast = fast_dmig(path)
    assert fast is not None and set(fast) == {"PATRN", "IDENT", "RANDM"}
    _same(fast, _card_by_card(path, monkeypatch))


def test_written_punch_with_grids_and_negative_values(tmp_path, monkeypatch):
    rng = np.random.default_rng(4)
    lines = ["$ comment", "GRID*                  1                     1.000000000E+00 2.000000000E+00",
             "*       3.000000000E+00", "DMIG    KAAX           0       6       2       0"]
    for j in range(1, 7):
        lines.append(f"DMIG*   {'KAAX':<16}{1:>16}{j:>16}")
        for i in range(1, j + 1):
            lines.append(f"*       {1:>16}{i:>16}{rng.standard_normal() * 10.0 ** rng.integers(-5, 9):16.9E}")
    path = tmp_path / "k.pch"
    path.write_text("\n".join(lines) + "\n")
    fast = fast_dmig(path)
    assert fast["KAAX"][1].shape == (21, 2)
    _same(fast, _card_by_card(path, monkeypatch))


@pytest.mark.parametrize("change", [
    lambda s: s.replace("DMIG*   PATRN", "DMIG*   patrn").replace("DMIG*", "dmig*"),  # lower-case card
    lambda s: s.replace("*       ", "*\t", 1),  # a tab
    lambda s: s.replace("1.000000000D+00", "1.00000000D+00 ", 1),  # another layout (strtod)
    lambda s: "BEGIN BULK\n" + s,
])
def test_other_forms_are_left_to_the_card_reader_or_read_alike(tmp_path, monkeypatch, change):
    path = tmp_path / "m.pch"
    path.write_text(change(_real_part(tmp_path).read_text()))
    fast = fast_dmig(path)
    if fast is not None:
        _same(fast, _card_by_card(path, monkeypatch))
