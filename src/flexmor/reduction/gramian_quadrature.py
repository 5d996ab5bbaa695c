"""The quadrature rule of the band-limited Gramians: Gauss-Legendre cells graded towards the resonances.

The integrands of :func:`flexmor.reduction.gramians.gramian_factors` are sums of Lorentzian
peaks ``1 / ((w - w_k)^2 + g_k^2)`` with half widths ``g_k = zeta_k w_k``. :func:`quadrature_rule`
gives every peak a cell of its own (split at the geometric midpoints between neighbouring
peaks) and grades the Gauss-Legendre panels of the cell geometrically towards the peak, so each
panel is as far from the poles ``w_k ± i g_k`` as it is long and the rule converges
geometrically in the number of nodes per panel (an hp-quadrature). Pieces without a peak are
integrated in ``log w``; an unbounded interval ends with the substitution ``w = d0 / t``.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import OptionError

__all__ = ["GRADING", "ZETA_PEAK", "quadrature_rule"]


def _gauss(a: float, b: float, n: int, panels: int):
    """Composite Gauss-Legendre nodes and weights on ``[a, b]``."""
    x, w = np.polynomial.legendre.leggauss(n)
    edges = np.linspace(a, b, panels + 1)
    h = np.diff(edges) / 2
    mid = (edges[:-1] + edges[1:]) / 2
    return (mid[:, None] + h[:, None] * x).ravel(), (h[:, None] * w).ravel()


#: Damping ratio above which a mode has no resonance peak worth a cell of its own.
ZETA_PEAK = 0.5

#: Ratio of neighbouring panel lengths of the meshes graded towards each peak.
GRADING = 3.0


def _log_gauss(d0: float, d1: float, nodes: int, panels: int):
    """Gauss nodes in ``u = log d`` on ``[d0, d1]`` (``d0 > 0``), one panel per decade at least."""
    np_ = max(panels, math.ceil(math.log10(d1 / d0)))
    u, wu = _gauss(math.log(d0), math.log(d1), nodes, np_)
    return np.exp(u), wu * np.exp(u)


def _tail(d0: float, nodes: int, panels: int):
    """Nodes of ``[d0, inf)`` by ``d = d0 / t``, ``t`` in ``(0, 1]``."""
    t, wt = _gauss(0.0, 1.0, nodes, panels)
    return d0 / t, wt * d0 / t ** 2


def _panels(edges, nodes: int):
    """Gauss-Legendre with ``nodes`` points on every panel between sorted ``edges``."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    e = np.unique(edges)
    h = np.diff(e) / 2
    mid = (e[:-1] + e[1:]) / 2
    return (mid[:, None] + h[:, None] * x).ravel(), (h[:, None] * w).ravel()


def _smooth(a: float, b: float, s_lo: float, s_hi: float, nodes: int, panels: int):
    """A cell without a peak: linear near 0, Gauss in ``log w`` over the decades, ``1/t`` tail."""
    ws, wts = [], []
    if a == 0:
        a1 = min(b, s_lo / 10)
        x, w = _gauss(0.0, a1, nodes, panels)
        ws.append(x), wts.append(w)
        a = a1
    b1 = min(b, 10 * s_hi) if math.isinf(b) else b
    if b1 > a:
        x, w = _log_gauss(a, b1, nodes, panels)
        ws.append(x), wts.append(w)
    if math.isinf(b):
        x, w = _tail(max(a, b1), nodes, panels)
        ws.append(x), wts.append(w)
    return np.concatenate(ws), np.concatenate(wts)


def _peak_cell(a: float, b: float, c: float, g: float, nodes: int, s_hi: float):
    """A cell ``[a, b]`` around the peak ``c`` (half width ``g``): panels graded towards ``c``.

    Break points ``c ± g GRADING^j`` (and ``c``): every panel is at least as far from the
    poles ``c ± i g`` as it is long, so Gauss-Legendre converges geometrically on each.
    """
    top = b if math.isfinite(b) else max(10 * s_hi, 10 * c)
    j = np.arange(0, 1 + math.ceil(math.log(max(top - c, c - a, g) / g, GRADING)))
    d = g * GRADING ** j
    edges = np.concatenate([[a, c, min(b, top)], c - d[c - d > a], c + d[c + d < top]])
    x, w = _panels(edges, nodes)
    if math.isinf(b):
        xt, wt = _tail(top - c, nodes, 1)
        x, w = np.concatenate([x, c + xt]), np.concatenate([w, wt])
    return x, w


def quadrature_rule(lo: float, hi: float, centres=(), widths=(), *, nodes: int = 6, panels: int = 1, scale=None):
    """Nodes and weights of ``∫_lo^hi g(w) dw`` for ``g`` with Lorentzian peaks (rad/s).

    One cell per peak (split at geometric midpoints between neighbouring peaks), with
    Gauss-Legendre panels graded geometrically towards the peak (break points
    ``w_k ± g_k 3^j``); an unbounded last cell ends with ``w - w_k = d / t``. Without
    peaks: Gauss in ``log w`` per decade between the ``scale`` bounds, linear near 0 and
    ``1/t`` beyond. Each panel stays as far from the poles ``w_k ± i g_k`` as it is long, so
    the rule converges geometrically in ``nodes`` (an hp-quadrature).

    Parameters
    ----------
    lo, hi : float
        Interval in rad/s, ``0 <= lo < hi``; ``hi`` may be ``inf``.
    centres, widths : array_like
        Resonances ``w_k`` and half widths ``g_k = zeta_k w_k`` (rad/s); modes with
        ``g_k >= ZETA_PEAK w_k`` or ``g_k <= 0`` have no peak and get no cell.
    nodes : int
        Gauss points per panel.
    panels : int
        Minimum number of panels of the pieces without a peak.
    scale : (float, float), optional
        Frequency range (rad/s) of the system for cells without a peak; default the range
        of ``centres`` (or 1).

    Returns
    -------
    w, weights : ndarray
    """
    if not (0 <= lo < hi):
        raise OptionError(f"quadrature interval must satisfy 0 <= lo < hi, got {lo}, {hi}")
    c = np.asarray(centres, float)
    g = np.asarray(widths, float)
    if scale is None:
        scale = (c.min(), c.max()) if c.size and c.min() > 0 else (1.0, 1.0)
    keep = (c > lo) & (c < hi) & (g > 0) & (g < ZETA_PEAK * c)
    c, g = c[keep], g[keep]
    order = np.argsort(c)
    c, g = c[order], g[order]
    if c.size > 1:  # merge (near-)multiple resonances, e.g. the two bending directions of a beam
        sel = np.concatenate([[True], np.diff(c) > 0.5 * np.minimum(g[1:], g[:-1])])
        c, g = c[sel], g[sel]
    if c.size == 0:
        return _smooth(lo, hi, scale[0], scale[1], nodes, panels)
    edges = np.concatenate([[lo], np.sqrt(c[:-1] * c[1:]), [hi]])
    parts = [_peak_cell(edges[k], edges[k + 1], c[k], g[k], nodes, scale[1]) for k in range(c.size)]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
