"""How a model's damping matrix ``D`` was obtained, as typed values.

:class:`NoDamping`, :class:`Rayleigh` (``D = alpha M + beta K``), :class:`BandMatched` (the
``--modal-damping ZETA`` realization: the Rayleigh damping with ratio ``zeta`` at both band
ends) and :class:`GivenDamping` (a matrix read from the FE files). The dictionary form
(``{"type": "rayleigh", "alpha": .., "beta": ..}``) exists only where damping is stored
(HDF5 attributes, JSON): :meth:`Damping.to_dict` and :func:`damping_from_dict`. A new kind
subclasses :class:`Damping` with its own ``kind`` and registers itself in :data:`KINDS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .errors import OptionError

__all__ = ["Damping", "NoDamping", "Rayleigh", "BandMatched", "GivenDamping", "KINDS", "damping_from_dict",
           "band_matched"]


@dataclass(frozen=True)
class Damping:
    """Base class: the damping of a model; ``kind`` is the ``type`` of its stored form."""

    kind: ClassVar[str] = ""

    def to_dict(self) -> dict:
        """The stored form: ``{"type": kind, ...fields}``."""
        return {"type": self.kind, **{k: v for k, v in self.__dict__.items()}}

    def ratios(self, freqs_hz) -> np.ndarray | None:
        """Modal damping ratios at the eigenfrequencies ``freqs_hz`` when known without the
        modes (None otherwise)."""
        return None

    def __str__(self) -> str:
        return str(self.to_dict())


@dataclass(frozen=True)
class NoDamping(Damping):
    """No damping (``D`` is None)."""

    kind: ClassVar[str] = "none"


@dataclass(frozen=True)
class GivenDamping(Damping):
    """A damping matrix given with the model (read from the FE files)."""

    kind: ClassVar[str] = "given"


@dataclass(frozen=True)
class Rayleigh(Damping):
    """Rayleigh damping ``D = alpha M + beta K``.

    Parameters
    ----------
    alpha : float
        Mass-proportional coefficient (1/s).
    beta : float
        Stiffness-proportional coefficient (s).
    """

    kind: ClassVar[str] = "rayleigh"
    alpha: float
    beta: float

    def to_dict(self) -> dict:
        return {"type": "rayleigh", "alpha": self.alpha, "beta": self.beta}

    def ratios(self, freqs_hz) -> np.ndarray:
        """``zeta = alpha/(2 w) + beta w/2`` at ``w = 2 pi f``."""
        w = 2 * np.pi * np.maximum(np.asarray(freqs_hz, float), 1e-30)
        return self.alpha / (2 * w) + self.beta * w / 2

    def matrix(self, M, K):
        """``alpha M + beta K``."""
        return (self.alpha * M + self.beta * K).tocsr()


@dataclass(frozen=True)
class BandMatched(Rayleigh):
    """The Rayleigh damping whose ratio equals ``zeta`` at both ends of ``band`` (``--modal-damping``).

    ``alpha = 2 zeta w1 w2/(w1+w2)``, ``beta = 2 zeta/(w1+w2)``; between the band ends the
    ratio is slightly lower, outside higher. Stored as its Rayleigh coefficients. Build it
    with :func:`band_matched`.
    """

    zeta: float
    band: tuple


def band_matched(zeta, band) -> BandMatched:
    """The :class:`BandMatched` damping of ratio ``zeta`` (in ``[0, 1)``) at the ends of ``band`` (Hz)."""
    z = float(zeta)
    if not 0 <= z < 1:
        raise OptionError(f"modal_damping must be in [0, 1), got {z}", params=("modal_damping",))
    w1, w2 = (2 * math.pi * float(f) for f in band)
    return BandMatched(2 * z * w1 * w2 / (w1 + w2), 2 * z / (w1 + w2), zeta=z, band=tuple(band))


#: ``type`` of the stored form -> class
KINDS: dict[str, type] = {c.kind: c for c in (NoDamping, GivenDamping, Rayleigh)}


def damping_from_dict(record: dict) -> Damping:
    """The damping of a stored form (``{"type": ..}``); an :class:`OptionError` for an unknown type."""
    kind = record.get("type") if isinstance(record, dict) else None
    if kind not in KINDS:
        raise OptionError(f"damping type {kind!r} is not known; known: {', '.join(KINDS)}")
    fields = {k: v for k, v in record.items() if k != "type"}
    try:
        return KINDS[kind](**fields)
    except TypeError:
        raise OptionError(f"damping {record!r} does not match type {kind!r}") from None
