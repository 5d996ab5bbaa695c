"""First-order state-space form of a reduced second-order body.

With the state ``x = [qr; qr']`` the reduced body ``Mr qr'' + Dr qr' + Kr qr = Br u``,
``y = Cr qr`` becomes

    x' = A x + B u,   y = C x + D u,
    A = [[0, I], [-Mr⁻¹ Kr, -Mr⁻¹ Dr]],  B = [[0], [Mr⁻¹ Br]],  C = [Cr, 0],  D = 0,

and, without inverting ``Mr``, the descriptor form ``E x' = Ae x + Be u`` with
``E = blkdiag(I, Mr)``, ``Ae = [[0, I], [-Kr, -Dr]]``, ``Be = [[0], [Br]]``. The file holds
``A B C D E Ae Be`` (``.npz``, or ``.mat`` by suffix).

References
----------
A. C. Antoulas, *Approximation of Large-Scale Dynamical Systems*, SIAM, 2005, ch. 4.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg as sla

from ..errors import ModelError
from ._registry import EXPORT_FORMATS
from .atomic import atomic_write

__all__ = ["StateSpace", "state_space", "to_control", "write_statespace"]


@dataclass
class StateSpace:
    """``x' = A x + B u``, ``y = C x + D u`` and the descriptor form ``E x' = Ae x + Be u``.

    ``input_names`` and ``output_names`` label the columns of ``B`` and the rows of ``C`` (the
    body's port SPECs, e.g. ``TIP:y``); empty when the body has none.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    E: np.ndarray
    Ae: np.ndarray
    Be: np.ndarray
    input_names: list = field(default_factory=list)
    output_names: list = field(default_factory=list)

    def _labels(self, names, n: int):
        """``names`` as signal labels when there is one distinct name per signal, else None."""
        names = [str(s) for s in names]
        return names if len(names) == n and len(set(names)) == n else None

    def to_scipy(self):
        """``scipy.signal.StateSpace`` of ``(A, B, C, D)``.

        SciPy's systems hold no signal names: the labels are attached to the object returned as
        its attributes ``input_names`` and ``output_names`` (lists of str, or None).
        """
        import scipy.signal

        sys = scipy.signal.StateSpace(self.A, self.B, self.C, self.D)
        sys.input_names = self._labels(self.input_names, self.B.shape[1])
        sys.output_names = self._labels(self.output_names, self.C.shape[0])
        return sys

    def to_control(self):
        """``control.StateSpace`` (python-control, when installed), its inputs and outputs
        labelled with :attr:`input_names` and :attr:`output_names` (python-control's default
        ``u[i]``, ``y[i]`` where a body has no names or repeats one)."""
        import control

        return control.ss(self.A, self.B, self.C, self.D, inputs=self._labels(self.input_names, self.B.shape[1]),
                          outputs=self._labels(self.output_names, self.C.shape[0]))

    def arrays(self) -> dict:
        """The matrices by name: ``A``, ``B``, ``C``, ``D`` and the descriptor form's ``E``, ``Ae``, ``Be``."""
        return {k: getattr(self, k) for k in ("A", "B", "C", "D", "E", "Ae", "Be")}


def state_space(body) -> StateSpace:
    """First-order form of a reduced body (see the module docstring).

    Raises
    ------
    ModelError
        When ``Mr`` is singular.
    """
    M, K = np.asarray(body.M, float), np.asarray(body.K, float)
    r = M.shape[0]
    Dm = np.zeros((r, r)) if body.D is None else np.asarray(body.D, float)
    Bm, Cm = np.asarray(body.B, float), np.asarray(body.C, float)
    try:
        lu = sla.cho_factor(M)
    except np.linalg.LinAlgError:
        raise ModelError("the reduced mass matrix is not positive definite; no state-space form") from None
    Z, Id = np.zeros((r, r)), np.eye(r)
    A = np.block([[Z, Id], [-sla.cho_solve(lu, K), -sla.cho_solve(lu, Dm)]])
    B = np.vstack([np.zeros_like(Bm), sla.cho_solve(lu, Bm)])
    C = np.hstack([Cm, np.zeros_like(Cm)])
    D = np.zeros((Cm.shape[0], Bm.shape[1]))
    E = np.block([[Id, Z], [Z, M]])
    Ae = np.block([[Z, Id], [-K, -Dm]])
    Be = np.vstack([np.zeros_like(Bm), Bm])
    return StateSpace(A, B, C, D, E, Ae, Be, input_names=list(getattr(body, "input_names", [])),
                      output_names=list(getattr(body, "output_names", [])))


def to_control(body):
    """``control.StateSpace`` (python-control) of ``body``'s first-order form (:func:`state_space`),
    its inputs and outputs labelled with the body's port names (:meth:`StateSpace.to_control`)."""
    return state_space(body).to_control()


def write_statespace(body, path, *, model=None) -> None:
    """Write ``A B C D E Ae Be`` to ``.npz`` (or ``.mat`` by suffix), atomically; ``model`` is unused."""
    data = state_space(body).arrays()
    if Path(path).suffix.lower() == ".mat":
        import scipy.io

        atomic_write(path, lambda tmp: scipy.io.savemat(tmp, data))
    else:
        def write(tmp):
            with open(tmp, "wb") as f:  # np.savez would append .npz to the temporary name
                np.savez(f, **data)

        atomic_write(path, write)


EXPORT_FORMATS.register("statespace", [".ss.npz", ".ss.mat"], write_statespace, aliases=["ss", "state-space"],
                        description="first-order state space A B C D (and descriptor E Ae Be) of a reduced body, "
                                    ".npz or .mat")
