"""Reduced bodies that span one subspace: the same body, reached by different methods.

A Galerkin body is determined by the span of its basis ``V``: two bases with one span give the
same reduced matrices up to a change of coordinates, hence the same eigenfrequencies, the same
FRF and the same error. Methods that build their bases from one set of solutions (the Gramian and
POD methods from one surrogate, a two-step truncation of it) can return one subspace; their
figures are then one figure, not several confirming each other.

Two bodies of one model share a subspace here when their reduced eigenfrequencies agree to
:data:`FREQ_RTOL` (a cheap necessary condition) and the sine of the largest principal angle between
their spans, ``||Q_2 - Q_1 Q_1^T Q_2||_2`` with orthonormal ``Q_1``, ``Q_2`` (Björck and Golub), is
at most :data:`SINE_TOL`. Whether spans are equal does not depend on the inner product, so the Euclidean
one serves.

References
----------
Björck, Å., Golub, G. H. (1973). Numerical methods for computing angles between linear subspaces.
Mathematics of Computation 27(123), 579-594.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

__all__ = ["FREQ_RTOL", "SINE_TOL", "SUBSPACE_MARK", "Span", "subspace_sine", "same_subspace", "subspace_groups",
           "body_label", "subspace_note"]

#: Relative agreement of the reduced eigenfrequencies that bodies of one subspace have.
FREQ_RTOL = 1e-8
#: Largest sine of the principal angles between the spans of bodies that share a subspace. Spans that differ
#: by an angle ``d`` give Rayleigh-Ritz eigenvalues that differ by ``O(d^2)``: :data:`FREQ_RTOL` is its square.
#: (Two truncations of one surrogate's Gramians differ by ~3e-7 in angle, their frequencies by ~1e-13.)
SINE_TOL = 1e-4


#: The words every :func:`subspace_note` holds.
SUBSPACE_MARK = "span one subspace"


def body_label(body) -> str:
    """``method r=order`` of a body."""
    return f"{body.method or 'reduced'} r={body.order}"


@dataclass(frozen=True)
class Span:
    """What the shared-subspace test needs of a body, kept after the body itself is gone.

    Attributes
    ----------
    label : str
        ``method r=order`` (:func:`body_label`).
    freqs : ndarray
        The body's reduced eigenfrequencies (Hz), sorted.
    V : ndarray or None
        Its basis (the body's own array, not a copy).
    """

    label: str
    freqs: np.ndarray
    V: np.ndarray | None

    @classmethod
    def of(cls, body) -> Span:
        """The span of ``body`` (a :class:`~flexmor.body.ReducedModel`)."""
        V = getattr(body, "V", None)
        return cls(body_label(body), np.sort(body.frequencies_hz()) if V is not None else np.zeros(0), V)


def _orthonormal(V) -> np.ndarray:
    V = np.asarray(V, float)
    Q, R = sla.qr(V, mode="economic", check_finite=False)
    d = np.abs(np.diag(R))
    return Q[:, d > 1e-12 * d.max(initial=0.0)] if d.size else Q


def subspace_sine(V1, V2) -> float:
    """Sine of the largest principal angle between the spans of ``V1`` and ``V2`` (1 where their ranks
    differ)."""
    Q1, Q2 = _orthonormal(V1), _orthonormal(V2)
    if Q1.shape != Q2.shape:
        return 1.0
    return float(min(np.linalg.norm(Q2 - Q1 @ (Q1.T @ Q2), 2), 1.0))


def same_subspace(a, b) -> float | None:
    """The sine of :func:`subspace_sine` where bodies (or their :class:`Span`) ``a`` and ``b`` span one
    subspace (equal reduced frequencies to :data:`FREQ_RTOL`, sine at most :data:`SINE_TOL`), else None.
    Bodies without a basis (``V`` None) or with bases of other shapes are not compared."""
    a, b = (x if isinstance(x, Span) else Span.of(x) for x in (a, b))
    Va, Vb = a.V, b.V
    if Va is None or Vb is None or np.shape(Va) != np.shape(Vb):
        return None
    fa, fb = a.freqs, b.freqs
    scale = max(float(np.abs(fa).max(initial=0.0)), 1.0)
    if fa.shape != fb.shape or not np.allclose(fa, fb, rtol=FREQ_RTOL, atol=FREQ_RTOL * scale):
        return None
    s = subspace_sine(Va, Vb)
    return s if s <= SINE_TOL else None


def subspace_groups(bodies) -> list[list[int]]:
    """Indices of ``bodies`` that span one subspace, grouped (groups of two or more, in order)."""
    bodies = list(bodies)
    group = list(range(len(bodies)))
    for j in range(len(bodies)):
        for i in range(j):
            if group[i] == i and same_subspace(bodies[i], bodies[j]) is not None:
                group[j] = i
                break
    out: dict[int, list[int]] = {}
    for j, g in enumerate(group):
        out.setdefault(g, []).append(j)
    return [g for g in out.values() if len(g) > 1]


def subspace_note(labels) -> str:
    """The note of bodies (their ``labels``) that span one subspace."""
    labels = list(labels)
    names = labels[0] if len(labels) == 1 else f"{', '.join(labels[:-1])} and {labels[-1]}"
    return (f"{names} {SUBSPACE_MARK} (equal reduced frequencies, principal angles below {SINE_TOL:g}): one body "
            "reached by different methods; their figures are one figure")
