import h5py
import numpy as np
import pytest

from flexmor.errors import ReadError
from flexmor.io import read_body, write_body
from flexmor.ports import make_ports
from flexmor.workflow import reduce_and_judge


def test_round_trip(clamped, tmp_path):
    ports = make_ports(clamped.with_rayleigh(1.0, 1e-6), ["TIP:y"])
    red, res = reduce_and_judge(clamped.with_rayleigh(1.0, 1e-6), "modal", 6, ports, band=(10, 2000))
    path = tmp_path / "body.h5"
    write_body(red, path)
    back = read_body(path)
    for name in ("M", "K", "D", "B", "C", "V", "dofs", "xyz", "node_ids"):
        np.testing.assert_array_equal(getattr(back, name), getattr(red, name))
    assert back.method == "modal" and back.input_names == ["TIP:y"]
    assert back.errors["band_error"] == pytest.approx(res["band_error"], rel=1e-14)
    assert back.damping.beta == 1e-6
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_foreign_hdf5_is_refused(tmp_path):
    p = tmp_path / "x.h5"
    with h5py.File(p, "w") as h:
        h["a"] = 1
    with pytest.raises(ReadError, match="not a flexmor reduced body"):
        read_body(p)
    q = tmp_path / "y.h5"
    q.write_text("hello")
    with pytest.raises(ReadError, match="not an HDF5 file"):
        read_body(q)


def _tiny_body(path):
    from flexmor.body import ReducedModel

    r = 3
    red = ReducedModel(M=np.eye(r), K=np.diag([1.0, 2.0, 3.0]), D=None, B=np.ones((r, 1)), C=np.ones((2, r)),
                       V=np.ones((12, r)), dofs=np.ones((12, 2), dtype=np.int64), method="modal")
    write_body(red, path)


@pytest.mark.parametrize("edit,message", [
    (lambda h: (h.__delitem__("K"), h.create_dataset("K", data=np.array([b"a", b"b"]))), "dataset 'K' is of type"),
    (lambda h: (h.__delitem__("K"), h.create_group("K")), "dataset 'K' is a group"),
    (lambda h: (h.__delitem__("K"), h.create_dataset("K", data=np.eye(4))), "inconsistent"),
    (lambda h: (h.__delitem__("B"), h.create_dataset("B", data=np.ones(3))), "expected 2 dimensions"),
    (lambda h: (h.__delitem__("V"), h.create_dataset("V", data=np.ones((11, 3)))), "inconsistent"),
    (lambda h: (h.__delitem__("dofs"), h.create_dataset("dofs", data=np.ones((12, 2)))), "expected integers"),
    (lambda h: (h.__delitem__("M"), h.__delitem__("K"), h.create_dataset("M", shape=(60000, 60000), dtype="f8"),
                h.create_dataset("K", shape=(60000, 60000), dtype="f8")), "implausibly large"),
    (lambda h: (h.__delitem__("C"),), "without dataset 'C'"),
    (lambda h: h["K"].__setitem__((0, 0), np.nan), "NaN or Inf"),
    (lambda h: h.attrs.__setitem__("info", np.arange(3)), "attribute 'info' is not a string"),
    (lambda h: h.attrs.__setitem__("info", "[1, 2]"), "must be JSON objects"),
], ids=["string-K", "group-K", "K-4x4", "B-1d", "V-rows", "float-dofs", "huge", "no-C", "nan", "info-array",
        "info-list"])
def test_damaged_reduced_body_is_refused_before_use(tmp_path, edit, message):
    p = tmp_path / "body.h5"
    _tiny_body(p)
    assert read_body(p).order == 3
    with h5py.File(p, "r+") as h:
        edit(h)
    with pytest.raises(ReadError, match="body.h5") as e:
        read_body(p)
    assert message in str(e.value)


def test_no_code_execution_from_data_anywhere_in_src():
    import re
    from pathlib import Path

    import flexmor

    bad = re.compile(r"\b(eval|exec|compile)\(|\bpickle\b|\bmarshal\b|\bshelve\b|allow_pickle\s*=\s*True|yaml\.load\(")
    hits = []
    for f in Path(flexmor.__file__).parent.rglob("*.py"):
        for i, line in enumerate(f.read_text().splitlines(), 1):
            code = line.split("#")[0]
            if bad.search(code) and "re.compile(" not in code and not code.strip().startswith(('"', "'")):
                hits.append(f"{f.name}:{i}: {line.strip()}")
            if "np.load(" in code and "allow_pickle=False" not in code:
                hits.append(f"{f.name}:{i}: np.load without allow_pickle=False")
    assert hits == []
