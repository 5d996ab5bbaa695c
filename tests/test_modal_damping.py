"""Modal damping (``--modal-damping ZETA``): the ratio zeta in every mode, not a Rayleigh fit.

Before, 2 % requested gave 0.22 % at 100 Hz and 3.3 % at 1648 Hz (Rayleigh damping matched at the
band ends). Now the reduced body has exactly zeta in each of its modes, the dense full FRF has it in
every mode, and the sparse full FRF in every mode below the band's top.
"""

import json

import numpy as np
import pytest
from helpers import CLAMPED

from flexmor.analysis.compare import FullResponse
from flexmor.cli import main
from flexmor.damping import ModalDamping, band_matched, damping_from_dict
from flexmor.dynamics.dense_frf import DenseResolvent
from flexmor.io import read_body
from flexmor.linalg.eigen import dense_eigenmodes
from flexmor.ports import make_ports
from flexmor.reduction import reduce
from flexmor.workflow import apply_damping

BAND = (10.0, 3000.0)


def _body_ratios(red):
    lam, psi = dense_eigenmodes(red.K, red.M)
    Dm = psi.T @ red.D @ psi
    w = np.sqrt(np.maximum(lam, 0.0))
    return w, np.diag(Dm) / (2 * np.maximum(w, 1e-300)), np.abs(Dm - np.diag(np.diag(Dm))).max()


@pytest.mark.parametrize("method", ["modal", "krylov", "craig-bampton"])
def test_the_body_has_the_ratio_in_every_mode(clamped, method):
    model = apply_damping(clamped, modal_damping=0.02, band=BAND)
    assert isinstance(model.damping, ModalDamping)
    opts = {"interface": ["TIP"]} if method == "craig-bampton" else {}
    red = reduce(model, method, 36 if opts else 20, make_ports(model, ["TIP:y"]), **opts)
    w, zeta, off = _body_ratios(red)
    np.testing.assert_allclose(zeta, 0.02, rtol=1e-9)
    assert off < 1e-9 * np.max(2 * 0.02 * w)  # diagonal in the body's modes
    # the Rayleigh fit of the same band: far from 2 % inside the band (the old meaning)
    assert band_matched(0.02, BAND).ratios([100.0])[0] < 0.15 * 0.02  # 0.27 % at 100 Hz


@pytest.mark.slow
@pytest.mark.parametrize("name", ["clamped", "free"])
def test_sparse_full_frf_matches_the_exact_modal_sum(name, request):
    """The sparse sweep corrects the modes below the band's top to zeta; the rest (quasi-static in
    the band) keep the Rayleigh realization: measured 8.1e-6 (clamped) and 1.6e-6 (free) of the peak."""
    model = apply_damping(request.getfixturevalue(name), modal_damping=0.02, band=BAND)
    ports = make_ports(model, ["TIP:y"])
    sparse = FullResponse(model, ports, BAND, path="direct", cache=False)
    exact = DenseResolvent(model.K, model.M, model.D, damping=model.damping)
    H = exact.frf(2 * np.pi * sparse.freqs, ports.B.toarray(), ports.C)
    assert np.abs(sparse.H - H).max() < 1e-4 * np.abs(H).max()
    # without the correction the Rayleigh fit is far off at the resonances inside the band
    plain = FullResponse(model.with_damping(band_matched(0.02, BAND)), ports, BAND, path="direct", cache=False)
    Hp = exact.frf(2 * np.pi * plain.freqs, ports.B.toarray(), ports.C)
    assert np.max(np.abs(plain.H - Hp) / np.abs(Hp)) > 0.1
    assert "exact in the" in sparse.grid["damping_note"]


def test_stored_and_reported(capsys, tmp_path):
    out = tmp_path / "m.h5"
    assert main(["reduce", CLAMPED, "--method", "modal", "--order", "8", "--input",
                 "TIP:y", "--modal-damping", "0.02", "--band", "10:3000", "-o", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    red = read_body(out)
    assert isinstance(red.damping, ModalDamping) and red.damping.zeta == 0.02
    assert damping_from_dict(red.damping.to_dict()) == red.damping
    np.testing.assert_allclose(_body_ratios(red)[1], 0.02, rtol=1e-9)
    assert res["band_error"] < 1e-3


def test_exudyn_body_gets_the_modal_damping(free, tmp_path):
    exu = pytest.importorskip("exudyn", reason="Exudyn is not installed (optional extra 'exudyn')")
    from exudyn.FEM import ObjectFFRFreducedOrderInterface

    from flexmor.io.exudyn import add_to_exudyn, write_exudyn

    model = apply_damping(free, modal_damping=0.02, band=BAND)
    red = reduce(model, "krylov", 12, make_ports(model, ["TIP:y", "TIP:z"]), band=BAND, rigid="exclude")
    mbs = exu.SystemContainer().AddSystem()
    body = add_to_exudyn(mbs, red, model)
    D = mbs.GetObjectParameter(body["oFFRFreducedOrder"], "dampingMatrixReduced")
    D = np.asarray(D.GetPythonObject() if hasattr(D, "GetPythonObject") else D)
    np.testing.assert_allclose(D, red.D, rtol=1e-12, atol=1e-12 * np.abs(red.D).max())
    np.testing.assert_allclose(_body_ratios(red)[1], 0.02, rtol=1e-9)
    path = tmp_path / "k.exudyn.npz"
    write_exudyn(red, path, model=model)
    cms = ObjectFFRFreducedOrderInterface()
    cms.LoadFromFile(str(path))  # the extra array does not disturb Exudyn's reader
    with np.load(path) as z:
        np.testing.assert_array_equal(z["dampingMatrixReduced"], red.D)
