import numpy as np

from flexmor.analysis.resonances import spurious_resonances
from flexmor.body import ReducedModel
from flexmor.dynamics.frf import frf_matrices


def test_a_mode_the_ports_do_not_see_is_told_with_advice_for_what_the_basis_was_built_for():
    """A body with a mode at 300 Hz its port does not load (B's second row 0) and no full mode there: the note
    names the mode; its advice depends on whether the basis holds the frame's inertia loads already."""
    w = 2 * np.pi * np.array([100.0, 300.0])
    K, M, D = np.diag(w ** 2), np.eye(2), np.diag(0.02 * w)
    B = np.array([[1.0], [0.0]])
    freqs = np.geomspace(10.0, 1000.0, 200)
    H = frf_matrices(K[:1, :1], M[:1, :1], D[:1, :1], B[:1], B[:1].T, 2 * np.pi * freqs)  # the full model: one mode
    notes = {}
    for n in (0, 6):
        body = ReducedModel(M=M, K=K, D=D, B=B, C=B.T, V=None, method="krylov",
                            info={"n_inertia_loads": n, "inertia_loads": "auto"})
        out = spurious_resonances(body, freqs, H, [100.0], [0.01])
        assert out["spurious_resonances_hz"] == [] and out["note"] is None  # the port does not see it: no error
        notes[n] = out["unseen_note"]
        assert notes[n].startswith("the body has a mode at 300 Hz in the band with no full mode within 3 %")
    assert notes[0].endswith("raise the order or add those loads as inputs")
    assert notes[6].endswith("raise the order (the basis is built for the frame's inertia loads already) or add the "
                             "other joints' loads as inputs")
