"""No reduction method forms a dense N x N matrix: peak traced memory of every registered method.

Every method of :data:`flexmor.reduction.METHODS` reduces the built-in clamped cantilever
(5,400 DOF, so a dense ``N x N`` array is 233 MB) with small orders and a narrow band;
``tracemalloc`` records every NumPy and Python allocation (a dense matrix from ``toarray()``,
``np.eye(N)`` or a dense eigen solve would show), the sparse factorizations' own C memory is
not traced. ``bench/no_dense.py`` runs the same at ~100k DOF in fresh processes and reports the
peak RSS as well.
"""

from __future__ import annotations

import tracemalloc

import pytest

from flexmor.models import cantilever
from flexmor.ports import make_ports
from flexmor.reduction import methods, reduce

BAND = (10.0, 200.0)  # the first bending pair (85 Hz) of the 1 m steel cantilever

#: method -> (order, options): small orders and cheap settings (one Gauss point per quadrature
#: panel; ``sobt`` resolves resonances up to its default cutoff, 10 x 200 Hz: 57 quadrature nodes)
CASES = {
    "modal": (6, {}),
    "guyan": (None, {"interface": ["TIP_CENTER"]}),
    "craig-bampton": (9, {"interface": ["TIP_CENTER"]}),
    "craig-chang": (9, {"interface": ["TIP_CENTER"]}),
    "herting": (9, {"interface": ["TIP_CENTER"]}),
    "krylov": (6, {"band": BAND}),
    "irka": (4, {"band": BAND, "max_iter": 3}),
    "adaptive": (6, {"band": BAND, "max_points": 3, "n_candidates": 50}),
    "sobt": (4, {"nodes": 1, "band": BAND}),
    "fw-sobt": (4, {"nodes": 1, "band": BAND}),
    "pod": (4, {"nodes": 1, "band": BAND}),
    "two-step": (4, {"intermediate": 12, "band": BAND}),
    "cms-krylov": (7, {"interface": ["TIP_CENTER"], "band": BAND}),
    "cms-gramian": (7, {"interface": ["TIP_CENTER"], "band": BAND, "nodes": 1}),
    "svdmor": (4, {"band": BAND}),
}


@pytest.fixture(scope="module")
def body():
    model = cantilever(5).with_rayleigh(5.0, 1e-6)
    return model, make_ports(model, ["TIP:y", "TIP:z", "TIP_CENTER:x"])


def test_every_method_is_covered():
    assert set(CASES) == set(methods())


@pytest.mark.parametrize("method", sorted(CASES))
def test_no_dense_n_by_n(body, method):
    model, ports = body
    n = model.n_dof
    order, opts = CASES[method]
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        red = reduce(model, method, order, ports, **opts)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert n > 5000 and red.order >= 3
    # one dense N x N array is 233 MB; measured peaks are ~30 MB (adaptive) and below
    assert peak < 8 * n * n / 4, f"{method}: peak {peak / 1e6:.1f} MB"
