"""The vectorized ``row col value`` parser: the same numbers as ``strtod`` for the layouts FE programs
print, and None (so the general parser and the line scanner decide) for anything else."""

import numpy as np
import pytest

from flexmor.io._fastparse import fast_triplets
from flexmor.io._text import parse_triplets


def _parse(text: str):
    return fast_triplets(np.frombuffer(text.encode(), dtype=np.uint8))


@pytest.mark.parametrize("fmt", ["{i} {j}  {x:20.13e}\n", "{i} {j} {x:.15e}\n", "{i},{j},{x:.16e}\r\n",
                                 "{i} {j} {x:.13E}\n", "{i:6d} {j:6d} {x:23.15E}\n"])
def test_same_doubles_as_strtod(fmt):
    rng = np.random.default_rng(7)
    n = 2000
    r, c = rng.integers(1, 10**6, n), rng.integers(1, 10**6, n)
    v = rng.standard_normal(n) * 10.0 ** rng.integers(-40, 40, n)
    v[::9] = 0.0
    text = "".join(fmt.format(i=i, j=j, x=x) for i, j, x in zip(r.tolist(), c.tolist(), v.tolist()))
    rows, cols, vals = _parse(text)
    ref = np.array([float(t) for t in text.replace(",", " ").split()]).reshape(-1, 3)
    np.testing.assert_array_equal(rows, ref[:, 0])
    np.testing.assert_array_equal(cols, ref[:, 1])
    np.testing.assert_array_equal(vals, ref[:, 2])  # bit for bit


def test_fortran_exponent():
    rows, cols, vals = _parse("1 2  1.5000000000000D+03\n3 4 -2.2500000000000D-01\n")
    assert rows.tolist() == [1, 3] and cols.tolist() == [2, 4] and vals.tolist() == [1500.0, -0.225]


@pytest.mark.parametrize("text", [
    "1 2 3.0e+00\n1 2 3 4.0e+00\n",  # a third index
    "1 2 3.0e+00\n12-4.0e+00\n",  # no separator before the sign
    "1 2 3.0e+00\n1 2 3.0e+0a\n",  # junk in the exponent
    "1 2 3.0e+00\n1.5 2 3.0e+00\n",  # non-integral index
    "1 2 3.0e+00\n 2 3.0e+00\n",  # an index missing
    "1 2 3.0e+00\n\n",  # a blank line
    "1 2 3.0e+00",  # no line end
    "1 2 3.0e+00\n1 2 3.00e+00\n",  # another layout
])
def test_anything_else_is_left_to_the_general_parser(text):
    assert _parse(text) is None


def test_trailing_blank_lines_and_other_layouts_read_alike(tmp_path):
    lines = [f"{i} {i} {float(i)!r}" for i in range(1, 50)] + [f"{i} {i + 1} {i:.13e}" for i in range(1, 50)]
    path = tmp_path / "m.txt"
    path.write_text("\n".join(lines) + "\n\n\n")
    rows, cols, vals = parse_triplets(path)
    assert rows.tolist() == list(range(49)) * 2 and vals[48] == 49.0 and vals[-1] == 49.0
