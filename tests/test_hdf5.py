import h5py
import numpy as np
import pytest

from flexmor.errors import ReadError
from flexmor.io import read
from flexmor.io.hdf5 import read_reduced, write_reduced
from flexmor.ports import make_ports
from flexmor.workflow import reduce_and_judge


def test_round_trip(clamped, tmp_path):
    ports = make_ports(clamped.with_rayleigh(1.0, 1e-6), ["TIP:y"])
    red, res = reduce_and_judge(clamped.with_rayleigh(1.0, 1e-6), "modal", 6, ports, band=(10, 2000))
    path = tmp_path / "body.h5"
    write_reduced(red, path)
    back = read(path)
    for name in ("M", "K", "D", "B", "C", "V", "dofs", "xyz", "node_ids"):
        np.testing.assert_array_equal(getattr(back, name), getattr(red, name))
    assert back.method == "modal" and back.input_names == ["TIP:y"]
    assert back.errors["band_error"] == pytest.approx(res["band_error"], rel=1e-14)
    assert back.damping["beta"] == 1e-6
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_foreign_hdf5_is_refused(tmp_path):
    p = tmp_path / "x.h5"
    with h5py.File(p, "w") as h:
        h["a"] = 1
    with pytest.raises(ReadError, match="not a flexmor reduced body"):
        read_reduced(p)
    q = tmp_path / "y.h5"
    q.write_text("hello")
    with pytest.raises(ReadError, match="not an HDF5 file"):
        read_reduced(q)
