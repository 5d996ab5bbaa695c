"""Plots: for notebooks (:func:`plot_frf`, :func:`plot_error`, :func:`plot_modes` draw on an Axes,
given or made with pyplot, and return it) and for the report (PNG bytes or files, drawn on a
:class:`matplotlib.figure.Figure` of their own: no pyplot, and the process's backend is left alone)."""

from __future__ import annotations

from ..io import atomic_write

__all__ = ["plot_frf", "plot_error", "plot_modes", "body_png", "figure_png", "frf_png", "frf_unit_label", "mac_png",
           "output_unit", "plot_rel_error", "rel_error_png", "singular_values_png", "time_error_curves", "time_png"]


# -- notebook plots: draw on an Axes and return it -----------------------------------------------
def _axes(ax):
    """``ax``, or the Axes of a new pyplot figure (the backend the user has chosen)."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    return plt.subplots()[1]


def plot_frf(freqs, H, *, ax=None, output: int = 0, input: int = 0, label: str | None = None, **style):
    """``|H(f)|`` of one input/output pair on log-log axes.

    Parameters
    ----------
    freqs : array_like
        Frequencies in Hz.
    H : ndarray, shape (n_freq, n_outputs, n_inputs)
        A frequency response (e.g. ``FullResponse.H``, :func:`flexmor.dynamics.frf.frf_reduced`).
    ax : matplotlib Axes, optional
        Drawn on; default a new pyplot figure.
    output, input : int
        The pair drawn.
    label : str, optional
        Legend entry.
    **style
        Passed to ``ax.loglog`` (``color``, ``lw``, ``ls`` ...).

    Returns
    -------
    matplotlib Axes
    """
    import numpy as np

    ax = _axes(ax)
    _draw_frf(ax, np.asarray(freqs, float), np.abs(np.asarray(H)[:, output, input]), label=label, **style)
    ax.set_xlabel("f [Hz]")
    ax.set_ylabel("|H|")
    if label is not None:
        ax.legend(fontsize=8)
    return ax


def plot_error(measures, *, ax=None, label: str | None = None, **style):
    """The pointwise relative error ``rel_error(f)`` of a judged body on log-log axes.

    Parameters
    ----------
    measures : ErrorMeasures or (freqs, rel_error)
        The judgement (:meth:`flexmor.analysis.compare.FullResponse.evaluate`), or a frequency
        grid (Hz) and the error on it.
    ax : matplotlib Axes, optional
        Drawn on; default a new pyplot figure.
    label : str, optional
        Legend entry.
    **style
        Passed to ``ax.loglog``.

    Returns
    -------
    matplotlib Axes
    """
    freqs, err = (measures.freqs_hz, measures.rel_error) if hasattr(measures, "rel_error") else measures
    ax = _axes(ax)
    _draw_rel_error(ax, {label: (freqs, err)}, legend=label is not None, **style)
    return ax


def plot_modes(check, *, ax=None, title: str | None = None):
    """The MAC matrix (full modes x reduced modes) of a modal check as a heat map.

    Parameters
    ----------
    check : dict or ndarray
        The result of :func:`flexmor.analysis.modal_check.modal_check` (its ``mac``), or a MAC
        matrix.
    ax : matplotlib Axes, optional
        Drawn on; default a new pyplot figure (with a colour bar).
    title : str, optional

    Returns
    -------
    matplotlib Axes
    """
    new = ax is None
    ax = _axes(ax)
    im = _draw_mac(ax, check["mac"] if isinstance(check, dict) else check, title or "")
    if new:
        ax.figure.colorbar(im, ax=ax, label="MAC")
    return ax


def _draw_frf(ax, freqs, mag, **style):
    ax.loglog(freqs, mag, **style)
    ax.grid(True, which="both", alpha=0.3)


def _draw_rel_error(ax, curves: dict, *, freqs=None, legend: bool = True, **style):
    """``rel_error(f)`` of each label on ``ax``; a curve is an array on ``freqs`` or an ``(f, err)`` pair."""
    for label, err in curves.items():  # an (f, err) pair brings its own frequency grid
        f, e = err if isinstance(err, tuple) else (freqs, err)
        ax.loglog(f, e, label=label, **{"lw": 1.2, **style})
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel(r"rel_error(f) = $\|H-\hat H\|_F / \|H\|_F$")
    ax.grid(True, which="both", alpha=0.3)
    if legend:
        ax.legend(fontsize=8)


def _draw_mac(ax, A, title: str):
    im = ax.imshow(A, vmin=0, vmax=1, cmap="viridis", origin="upper", aspect="auto")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("reduced mode", fontsize=8)
    ax.set_ylabel("full mode", fontsize=8)
    return im


def plot_rel_error(freqs, curves: dict, path, *, title: str = "") -> None:
    """Log-log plot of ``rel_error(f)`` for several reduced bodies, saved as PNG.

    Parameters
    ----------
    freqs : ndarray
        Frequency grid in Hz.
    curves : dict of str to ndarray
        Label -> ``rel_error`` on ``freqs``.
    path : path-like
        Output PNG file.
    """
    fig = _rel_error_figure(freqs, curves, title)
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))


def _rel_error_figure(freqs, curves: dict, title: str = ""):
    fig = _figure(figsize=(8, 4.8), dpi=110)
    ax = fig.subplots()
    _draw_rel_error(ax, curves, freqs=freqs)
    if title:
        ax.set_title(title)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.11, top=0.92 if title else 0.96)  # fixed: no layout pass
    return fig


# -- report figures (PNG bytes for embedding) ---------------------------------------------------
def _figure(**kwargs):
    """A :class:`matplotlib.figure.Figure` outside pyplot (rendered by ``savefig`` alone)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def figure_png(fig, *, dpi: int = 100) -> bytes:
    """Render a matplotlib figure to PNG bytes (a pyplot figure is closed)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    import sys

    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close(fig)
    return buf.getvalue()


def rel_error_png(freqs, curves: dict, *, title: str = "") -> bytes:
    """:func:`plot_rel_error` as PNG bytes; a curve may be a pair ``(freqs, rel_error)`` of its own grid."""
    return figure_png(_rel_error_figure(freqs, curves, title))


def _unit_label(text: str, unit: str) -> str:
    """``text [unit]``, or ``text`` without a unit."""
    return f"{text} [{unit}]" if unit else text


def frf_unit_label(output, input, units) -> str:
    """``|H| [m/N]``: the axis label of the transfer function between two ports in ``units`` (the
    system of the numbers drawn; None: as given, no unit)."""
    from ..units import frf_unit

    return _unit_label("|H|", frf_unit(output, input, units) if units else "")


def output_unit(names, units) -> str:
    """The unit of outputs ``names`` in ``units``: ``m``, ``rad``, ``m, rad`` or ``""`` (as given, or a port
    without direction)."""
    from ..units import port_kind, unit_system

    kinds = [port_kind(n) for n in names]
    if not units or None in kinds:
        return ""
    return ", ".join(u for k, u in (("translation", unit_system(units).length_unit), ("rotation", "rad"))
                     if k in kinds)


def frf_png(freqs, H, reduced: dict, input_names, output_names, *, max_pairs: int = 9, units=None) -> bytes:
    """``|H_ij(f)|`` of the full model (black) and each reduced body, one panel per pair.

    ``H`` has shape (n_freq, n_outputs, n_inputs), or is a dict of such arrays: the references
    the bodies are judged against, by name (e.g. ``{"full model, elastic part": ...}``; drawn
    black, solid then dashed); a plain array is named ``full``. ``reduced`` maps labels to arrays
    of the same shape. At most ``max_pairs`` pairs are drawn (outputs fastest); pairs whose peak
    is below ``1e-8`` of the largest one (zero by symmetry, round-off only) are left out. ``units``
    (the system of the numbers, e.g. ``SI``; None: as given) puts the unit of each pair on its axis
    (``|H| [m/N]``, ``|H| [rad/(N m)]``).
    """
    import numpy as np

    refs = dict(H) if isinstance(H, dict) else {"full": H}
    H0 = next(iter(refs.values()))
    peak = np.max([np.abs(R).max(axis=0) for R in refs.values()], axis=0)
    pairs = [(i, j) for j in range(H0.shape[2]) for i in range(H0.shape[1])
             if peak[i, j] >= 1e-8 * peak.max()][:max_pairs]  # numerically zero cross terms are left out
    nc = min(3, len(pairs))
    nr = -(-len(pairs) // nc)
    fig = _figure(figsize=(4.2 * nc, 3.2 * nr))
    axes = fig.subplots(nr, nc, squeeze=False)
    fig.subplots_adjust(left=0.32 / nc, right=0.98, bottom=0.5 / (3.2 * nr), top=1 - 0.3 / (3.2 * nr), wspace=0.3,
                        hspace=0.45)
    for ax, (i, j) in zip(axes.flat, pairs):
        for k, (name, R) in enumerate(refs.items()):
            _draw_frf(ax, freqs, np.abs(R[:, i, j]), color="k", ls=["-", "--", ":"][k % 3], lw=2.0, label=name)
        for label, Hr in reduced.items():
            _draw_frf(ax, freqs, np.abs(Hr[:, i, j]), lw=1.0, label=label)
        ax.set_title(f"{output_names[i]} / {input_names[j]}", fontsize=9)
        ax.set_xlabel("f [Hz]", fontsize=8)
        ax.set_ylabel(frf_unit_label(output_names[i], input_names[j], units), fontsize=8)
    for ax in list(axes.flat)[len(pairs):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    return figure_png(fig)


def singular_values_png(values: dict) -> bytes:
    """Semilog plot of decaying singular values (Hankel, POD) per label."""
    import numpy as np

    fig = _figure(figsize=(7, 4))
    ax = fig.subplots()
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.12, top=0.96)
    for label, s in values.items():
        s = np.asarray(s, float)
        ax.semilogy(np.arange(1, s.size + 1), s / s[0] if s.size and s[0] > 0 else s, "o-", ms=3, label=label)
    ax.set_xlabel("index")
    ax.set_ylabel(r"$\sigma_k / \sigma_1$")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return figure_png(fig)


def campbell_png(speeds, full, bodies: dict, *, reference: str = "full model", multiples=(1, 2)) -> bytes:
    """Campbell diagram: the full model's frequencies (Hz) over the speeds (rad/s) as lines, each body's as
    markers, and the lines of ``k`` times the speed."""
    import numpy as np

    fig = _figure(figsize=(7, 4.5))
    ax = fig.subplots()
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.12, top=0.96)
    w = np.asarray(speeds, float)
    F = np.asarray(full, float)
    for j in range(F.shape[1]):
        ax.plot(w, F[:, j], "-", color="k", lw=1.2, label=reference if j == 0 else None)
    marks = "os^vD<>"
    for i, (label, G) in enumerate(bodies.items()):
        G = np.asarray(G, float)
        for j in range(G.shape[1]):
            ax.plot(w, G[:, j], marks[i % len(marks)], ms=4, mfc="none", color=f"C{i}", label=label if j == 0 else None)
    top = np.nanmax(F) * 1.05 if F.size else 1.0
    for k in multiples:
        ax.plot(w, k * w / (2 * np.pi), ":", color="0.5", lw=1, label=f"{k} x speed")
    ax.set_ylim(0, top)
    ax.set_xlabel("speed [rad/s]")
    ax.set_ylabel("frequency [Hz] (turning frame)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return figure_png(fig)


def path_error_png(paths: dict) -> bytes:
    """Band error against the position along each moving load's path (:func:`flexmor.moving.judge_path`), one
    line per body and path, the worst position marked."""
    import numpy as np

    fig = _figure(figsize=(7, 3.8))
    ax = fig.subplots()
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.14, top=0.95)
    for i, (label, recs) in enumerate(paths.items()):
        for rec in recs:
            s = np.asarray(rec["positions"]["s"], float)
            e = np.asarray([np.nan if v is None else v for v in rec["positions"]["band_error"]], float)
            ax.semilogy(s, np.maximum(e, 1e-300), "-", color=f"C{i}", lw=1.2, label=f"{label}: {rec['path']}")
            ax.semilogy([rec["worst_s"]], [rec["path_max_band_error"]], "o", color=f"C{i}", mfc="none")
    ax.set_xlabel("position along the path s [m]")
    ax.set_ylabel("band_error of a unit force at s")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return figure_png(fig)


def crossing_png(crossings: dict, *, reference: str = "full model") -> bytes:
    """The deflection under a force crossing the path over time: the full model (lines) and each body (dashed),
    one panel per speed of the first body's crossings (:func:`flexmor.moving.crossing`)."""
    import numpy as np

    first = next(iter(crossings.values()))
    n = max(1, len(first))
    fig = _figure(figsize=(7, 2.6 * n))
    axes = fig.subplots(n, 1, squeeze=False)[:, 0]
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.5 / (2.6 * n), top=1 - 0.3 / (2.6 * n), hspace=0.55)
    for j, ax in enumerate(axes):
        c0 = first[j]
        ax.plot(np.asarray(c0["t"]), np.asarray(c0["under_load"]), "-", color="k", lw=1.2, label=reference)
        for i, (label, cs) in enumerate(crossings.items()):
            match = [c for c in cs if c["speed"] == c0["speed"] and c["path"] == c0["path"]]
            for c in match[:1]:
                ax.plot(np.asarray(c["t"]), np.asarray(c["under_load_body"]), "--", color=f"C{i}", lw=1.1,
                        label=f"{label} (max error {c['time_max_error']:.1e})")
        ax.set_title(f"{c0['path']}: {c0['force']:g} N crossing at {c0['speed']:g} m/s", fontsize=9)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("deflection under the load [m]", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    return figure_png(fig)


def mac_png(macs: dict) -> bytes:
    """MAC matrices (full modes x reduced modes) as heat maps, one panel per body."""
    n = max(1, len(macs))
    nc = min(3, n)
    nr = -(-n // nc)
    fig = _figure(figsize=(3.8 * nc, 3.4 * nr))
    axes = fig.subplots(nr, nc, squeeze=False)
    fig.subplots_adjust(left=0.3 / nc, right=0.98, bottom=0.4 / (3.4 * nr), top=1 - 0.3 / (3.4 * nr), wspace=0.35,
                        hspace=0.4)
    im = None
    for ax, (label, A) in zip(axes.flat, macs.items()):
        im = _draw_mac(ax, A, label)
    for ax in list(axes.flat)[len(macs):]:
        ax.axis("off")
    if im is not None:
        fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8, label="MAC")
    return figure_png(fig)


def time_error_curves(references: dict, reduced: dict, reference_of: dict) -> dict:
    """``||y - ŷ||(t) / max_t ||y||`` of each body against its reference (the curves of :func:`time_png`).

    ``references`` maps names to responses (n_t, n_outputs, n_cases), ``reduced`` labels to responses
    of that shape and ``reference_of`` labels to reference names. The Frobenius norm runs over all
    channels at each time, as in :func:`flexmor.dynamics.time.time_errors`: the peak of a curve is
    the body's ``time_max_error``.
    """
    import numpy as np

    out = {}
    for label, yr in reduced.items():
        yk = references[reference_of[label]]
        peak = max(np.max(np.linalg.norm(yk.reshape(yk.shape[0], -1), axis=1)), np.finfo(float).tiny)
        out[label] = np.linalg.norm((yk - yr).reshape(yk.shape[0], -1), axis=1) / peak
    return out


def time_png(t, y, reduced: dict, labels, *, quantity: str = "displacement", max_channels: int = 4,
             reference_of: dict | None = None) -> bytes:
    """Time responses (top) and the error norm ``||y - ŷ||(t) / max_t ||y||`` per body (bottom).

    ``y`` has shape (n_t, n_outputs, n_cases), or is a dict of such arrays: the references the
    bodies are judged against, by name (drawn thick, solid then dashed); a plain array is named
    ``full``. ``reduced`` maps labels to arrays of that shape, ``reference_of`` labels to the
    name of their reference (default the first); each body's error is taken against its own
    reference and divided by that reference's peak, so the peak of its curve is its
    ``time_max_error`` (:func:`flexmor.dynamics.time.time_errors`). ``labels[(i, j)]`` names
    channel ``y[:, i, j]``.
    """
    import numpy as np

    refs = dict(y) if isinstance(y, dict) else {"full": y}
    first = next(iter(refs))
    reference_of = {lb: (reference_of or {}).get(lb, first) for lb in reduced}
    y0 = refs[first]
    chans = [(i, j) for j in range(y0.shape[2]) for i in range(y0.shape[1])][:max_channels]
    fig = _figure(figsize=(9, 6.4))
    axes = fig.subplots(2, 1, sharex=True)
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.08, top=0.96, hspace=0.06)
    from matplotlib.lines import Line2D

    ref_ls, red_ls = ["-", "--", ":"], ["-", "--", ":", "-."]
    for n, (i, j) in enumerate(chans):
        for k, yk in enumerate(refs.values()):
            axes[0].plot(t, yk[:, i, j], color=f"C{n}", lw=2.2, alpha=0.5, ls=ref_ls[k % 3])
        for k, yr in enumerate(reduced.values()):
            axes[0].plot(t, yr[:, i, j], color=f"C{n}", lw=0.9, ls=red_ls[k % 4])
    # one legend entry per channel (colour), reference (thick) and body (thin)
    handles = [Line2D([], [], color=f"C{n}", lw=2.2, alpha=0.5, label=labels[c]) for n, c in enumerate(chans)]
    handles += [Line2D([], [], color="k", lw=2.2, alpha=0.5, ls=ref_ls[k % 3], label=name)
                for k, name in enumerate(refs)]
    handles += [Line2D([], [], color="k", lw=0.9, ls=red_ls[k % 4], label=label) for k, label in enumerate(reduced)]
    axes[0].set_ylabel(quantity)
    axes[0].legend(handles=handles, fontsize=7, ncol=2)
    axes[0].grid(True, alpha=0.3)
    tops = []
    for label, e in time_error_curves(refs, reduced, reference_of).items():
        tops.append(max(float(np.max(e)), 1e-16))
        name = label if len(refs) == 1 else f"{label} (vs {reference_of[label]})"
        axes[1].semilogy(t, np.maximum(e, 1e-16), lw=1.0, label=name)
    if tops:
        axes[1].set_ylim(bottom=max(1e-3 * min(tops), 1e-16))
    axes[1].set_ylabel(r"$\|y-\hat y\|(t) / \max_t\|y\|$")
    axes[1].set_xlabel("t [s]")
    axes[1].grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=7)
    return figure_png(fig)


def body_png(xyz, marks: dict, *, title: str = "", units=None) -> bytes:
    """3D scatter of the nodes (grey) with marked node groups (label -> coordinates (k, 3)); ``units``
    (the system of the coordinates; None: as given) labels the axes ``x [m]``."""
    import numpy as np

    from ..units import unit_system

    fig = _figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=2, c="0.6", alpha=0.5, label=f"nodes ({len(xyz)})")
    styles = [("o", 60), ("^", 30), ("s", 90), ("D", 30)]
    for k, (label, pts) in enumerate(marks.items()):
        pts = np.asarray(pts, float).reshape(-1, 3)
        if pts.size:
            mk, s = styles[k % len(styles)]
            ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=s, marker=mk, color=f"C{k}", depthshade=False,
                       label=f"{label}: {len(pts)} node{'s' if len(pts) != 1 else ''}")  # nodes, not DOFs
    span = np.ptp(xyz, axis=0) if len(xyz) else np.ones(3)
    ax.set_box_aspect(np.maximum(span, 0.15 * max(span.max(), 1e-30)))  # slender bodies stay visible
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(3))
    length = unit_system(units).length_unit if units else ""
    ax.set_xlabel(_unit_label("x", length))
    ax.set_ylabel(_unit_label("y", length))
    ax.set_zlabel(_unit_label("z", length))
    ax.legend(fontsize=7, loc="upper left")
    if title:
        ax.set_title(title, fontsize=9)
    return figure_png(fig)
