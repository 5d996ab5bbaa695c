"""Checks at the boundaries of the Python API: a bad basis, bad port matrices or a mistyped option is
refused where it is given, by a FlexmorError that names the argument and says what is wrong."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from flexmor.analysis.compare import FullResponse
from flexmor.basis import Basis
from flexmor.errors import FlexmorError, ModelError, OptionError, PortError
from flexmor.options import check_order
from flexmor.ports import Ports, make_ports
from flexmor.projection import project
from flexmor.reduction import reduce
from flexmor.reduction.krylov import krylov
from flexmor.reduction.modal import modal


@pytest.fixture(scope="module")
def setup(clamped):
    ports = make_ports(clamped, ["TIP:y"], ["TIP:y", "TIP:z"])
    return clamped, ports, modal(clamped, ports, 6).V


def _refused(cls, param, match, fn, *args, **kw):
    with pytest.raises(cls, match=match) as exc:
        fn(*args, **kw)
    assert isinstance(exc.value, FlexmorError) and param in exc.value.params
    assert param in str(exc.value)
    return exc.value


# -- project(model, basis, ports) -------------------------------------------------------------------------------------
def test_project_takes_a_plain_array(setup):
    model, ports, V = setup
    body = project(model, V, ports)
    ref = project(model, Basis(V, "modal"), ports)
    assert body.method == "custom" and body.order == 6
    np.testing.assert_array_equal(body.K, ref.K)
    np.testing.assert_array_equal(body.C, ref.C)
    np.testing.assert_array_equal(project(model, sp.csr_matrix(V), ports).M, ref.M)  # sparse: made dense


def test_project_refuses_nan_and_inf(setup):
    model, ports, V = setup
    for bad in (np.nan, np.inf):
        W = V.copy()
        W[5, 3] = bad
        _refused(ModelError, "basis", r"basis has NaN or Inf values \(in 1 of its 6 columns, the first column 3\)",
                 project, model, W, ports)


def test_project_refuses_a_complex_basis(setup):
    model, ports, V = setup
    _refused(ModelError, "basis", "basis is complex", project, model, V * (1 + 1e-3j), ports)
    body = project(model, V.astype(complex), ports)  # a zero imaginary part is a real basis
    np.testing.assert_array_equal(body.K, project(model, V, ports).K)


def test_project_refuses_a_rank_deficient_basis(setup):
    model, ports, V = setup
    _refused(ModelError, "basis", "rank deficient: its 7 columns span 6 dimensions", project, model,
             np.hstack([V, V[:, [2]]]), ports)
    mix = V[:, [0]] + 0.5 * V[:, [4]]
    _refused(ModelError, "basis", "rank deficient: its 7 columns span 6 dimensions", project, model,
             np.hstack([V, mix]), ports)
    _refused(ModelError, "basis", "zero column", project, model, np.hstack([V, np.zeros((model.n_dof, 1))]), ports)
    # far apart in scale, yet independent: accepted (the test does not depend on the columns' lengths)
    body = project(model, V * np.logspace(-12, 12, 6), ports)
    assert body.order == 6


def test_project_refuses_a_wrong_shape_or_type(setup):
    model, ports, V = setup
    _refused(ModelError, "basis", rf"basis has shape \({model.n_dof - 1}, 6\), expected \({model.n_dof}, r\)",
             project, model, V[1:], ports)
    _refused(ModelError, "basis", "has no column", project, model, V[:, :0], ports)
    _refused(ModelError, "basis", "real numbers", project, model, "V", ports)
    _refused(PortError, "ports", "ports must be a Ports", project, model, V, ["TIP:y"])


# -- Ports ------------------------------------------------------------------------------------------------------------
def test_ports_from_dense_arrays_equal_the_ports_of_specs(setup):
    model, ports, V = setup
    B, C = ports.B.toarray(), ports.C.toarray()
    p = Ports.from_arrays(B, C, ["TIP:y"], ["TIP:y", "TIP:z"], model=model)
    assert sp.issparse(p.B) and sp.issparse(p.C)
    assert (p.B != ports.B).nnz == 0 and (p.C != ports.C).nnz == 0
    q = Ports.from_arrays(sp.csc_matrix(B))  # collocated, named u1
    assert q.input_names == q.output_names == ["u1"] and (q.C != ports.B.T).nnz == 0
    np.testing.assert_array_equal(project(model, V, p).B, project(model, V, ports).B)


def test_ports_from_arrays_name_what_is_wrong(setup):
    model, ports, _ = setup
    B = ports.B.toarray()
    _refused(PortError, "C", "B has 270 rows .* but C has 269 columns", Ports.from_arrays, B, np.ones((1, 269)))
    _refused(PortError, "B", r"B must be 2-D, got shape \(270,\) \(one column: B\[:, None\]\)", Ports.from_arrays,
             B[:, 0])
    _refused(PortError, "B", "270 rows, but the model has 297 equations", Ports.from_arrays, B, model=297)
    _refused(PortError, "input_names", "input_names must name each of the 1 columns of B, got 2", Ports.from_arrays,
             B, None, ["a", "b"])
    _refused(PortError, "B", "NaN or Inf", Ports.from_arrays, B * np.nan)
    _refused(PortError, "B", "real numbers", Ports.from_arrays, B * 1j)


def test_ports_constructor_converts_dense_arrays_and_checks_them(setup):
    """``Ports(B, C, ...)`` with dense arrays works in a method that needs sparse ones (was an
    AttributeError inside the method); mismatched arrays are refused when the ports are made."""
    model, ports, _ = setup
    dense = Ports(ports.B.toarray(), ports.C.toarray(), ["TIP:y"], ["TIP:y", "TIP:z"])
    V1 = krylov(model, dense, 4).V
    V2 = krylov(model, ports, 4).V
    np.testing.assert_allclose(np.abs(V1.T @ V2), np.eye(4), atol=1e-8)
    _refused(PortError, "B", "B has 270 rows .* but C has 1 columns", Ports, ports.B, ports.B, ["a"], ["b"])
    _refused(PortError, "output_names", "output_names must name each of the 2 rows of C, got 1", Ports,
             ports.B, ports.C, ["a"], ["b"])


# -- options ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order, match", [(True, "got True of type bool"), ("8", "got '8' of type str"),
                                          (8.5, "got 8.5"), (0, "got 0"), (float("nan"), "got nan")])
def test_reduce_refuses_an_order_that_is_not_a_positive_integer(setup, order, match):
    model, ports, _ = setup
    _refused(OptionError, "order", "order must be a positive integer, " + match, reduce, model, "modal", order, ports)


def test_check_order_takes_integers():
    assert check_order(np.int64(6)) == 6 and type(check_order(np.int64(6))) is int
    assert check_order(6.0) == 6 and check_order(None) is None


@pytest.mark.parametrize("band, match", [(1000, "band must be a pair .FMIN, FMAX. in Hz, got 1000"),
                                         (None, "band is needed"), ((100.0, 10.0), "0 < FMIN < FMAX"),
                                         ("10:x", "band must look like A:B")])
def test_full_response_names_a_bad_band(setup, band, match):
    model, ports, _ = setup
    _refused(OptionError, "band", match, FullResponse, model, ports, band)


@pytest.mark.parametrize("method, options, param, match", [
    ("craig-bampton", {"interface": "TIP"}, "interface", r"interface must be a list \(e.g. \['TIP'\]\), got 'TIP'"),
    ("modal", {"sigma": "x"}, "sigma", "sigma must be a number, got 'x' of type str"),
    ("krylov", {"moments": True}, "moments", "moments must be an integer, got True of type bool"),
    ("irka", {"max_iter": "50"}, "max_iter", "max_iter must be an integer, got '50' of type str"),
])
def test_reduce_refuses_method_options_of_the_wrong_type(setup, method, options, param, match):
    model, ports, _ = setup
    _refused(OptionError, param, match, reduce, model, method, 6, ports, **options)
