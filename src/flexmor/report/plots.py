"""Plots (matplotlib, Agg backend; written atomically)."""

from __future__ import annotations

from ..io import atomic_write

__all__ = ["plot_rel_error"]


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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.8), dpi=110)
    for label, err in curves.items():
        ax.loglog(freqs, err, label=label, lw=1.2)
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel(r"rel_error(f) = $\|H-\hat H\|_F / \|H\|_F$")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)
