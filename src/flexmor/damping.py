"""How a model's damping matrix ``D`` was obtained, as typed values.

:class:`NoDamping`, :class:`Rayleigh` (``D = alpha M + beta K``), :class:`BandMatched` (the
Rayleigh damping with ratio ``zeta`` at both band ends), :class:`ModalDamping`
(``--modal-damping ZETA``: the ratio ``zeta`` in every mode) and :class:`GivenDamping` (a matrix
read from the FE files). The dictionary form
(``{"type": "rayleigh", "alpha": .., "beta": ..}``) exists only where damping is stored
(HDF5 attributes, JSON): :meth:`Damping.to_dict` and :func:`damping_from_dict`. A new kind
subclasses :class:`Damping` with its own ``kind`` and registers itself in :data:`KINDS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .errors import OptionError, real_finite

__all__ = ["Damping", "NoDamping", "Rayleigh", "BandMatched", "ModalDamping", "GivenDamping", "KINDS",
           "damping_from_dict", "band_matched", "modal_damping", "describe_damping"]


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

    def __post_init__(self):
        """Refuse a coefficient that is not a real, finite number >= 0 (complex, NaN, Inf, text), naming it."""
        for name in ("alpha", "beta"):
            value = real_finite(getattr(self, name), name, "a real, finite number (a Rayleigh coefficient)")
            if value.ndim:
                raise OptionError(f"{name} must be one number (a Rayleigh coefficient), got shape {value.shape}",
                                  params=(name,))
            object.__setattr__(self, name, float(value))
        if self.alpha < 0 or self.beta < 0:
            raise OptionError(f"Rayleigh coefficients must be finite and >= 0, got alpha={self.alpha}, "
                              f"beta={self.beta}", params=tuple(n for n in ("alpha", "beta") if getattr(self, n) < 0))

    def to_dict(self) -> dict:
        """The stored form: ``{"type": "rayleigh", "alpha": alpha, "beta": beta}`` (a band-matched one too)."""
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
    """The Rayleigh damping whose ratio equals ``zeta`` at both ends of ``band`` (``--band-rayleigh``).

    ``alpha = 2 zeta w1 w2/(w1+w2)``, ``beta = 2 zeta/(w1+w2)``; between the band ends the
    ratio is slightly lower, outside higher. Stored as its Rayleigh coefficients. Build it
    with :func:`band_matched`.
    """

    zeta: float
    band: tuple


def band_matched(zeta, band, *, name: str = "band_rayleigh") -> BandMatched:
    """The :class:`BandMatched` damping of ratio ``zeta`` (in ``[0, 1)``) at the ends of ``band`` (Hz);
    ``name`` is the parameter an error names."""
    z = real_finite(zeta, name, "a damping ratio (a real number)")
    if z.ndim:
        raise OptionError(f"{name} must be one damping ratio, got shape {z.shape}", params=(name,))
    z = float(z)
    if not 0 <= z < 1:
        raise OptionError(f"{name} must be in [0, 1), got {z}", params=(name,))
    w1, w2 = (2 * math.pi * float(f) for f in band)
    return BandMatched(2 * z * w1 * w2 / (w1 + w2), 2 * z / (w1 + w2), zeta=z, band=tuple(band))


@dataclass(frozen=True)
class ModalDamping(BandMatched):
    """Modal damping: the ratio ``zeta`` in every mode (``--modal-damping ZETA``).

    Wherever the modes are known, each has exactly the ratio ``zeta``: the reduced body
    (:meth:`reduced_matrix`, ``Dr = Mr Psi diag(2 zeta w) Psi^T Mr`` in its own modes, what the
    MBS code receives), the full FRF of the dense path, and the modes below the band's top on
    the sparse paths (:class:`flexmor.analysis.compare.FullResponse` corrects their share).
    A sparse matrix of the full model, needed where ``s^2 M + s D + K`` is factorized (the
    methods' expansion points, the sparse FRF before the correction), is the Rayleigh
    realization matched at the band ends (:class:`BandMatched`: ``alpha``, ``beta``). Rigid-body
    modes are undamped.
    """

    kind: ClassVar[str] = "modal"

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "band", tuple(float(b) for b in self.band))

    def to_dict(self) -> dict:
        """The stored form: ``{"type": "modal", "zeta", "band", "alpha", "beta"}`` (the ratio and its realization)."""
        return {"type": "modal", "zeta": self.zeta, "band": list(self.band), "alpha": self.alpha,
                "beta": self.beta}

    def ratios(self, freqs_hz) -> np.ndarray:
        """``zeta`` for every elastic mode, 0 for rigid-body modes (``f`` below 1e-6 of the largest)."""
        f = np.asarray(freqs_hz, float)
        z = np.full(f.shape, self.zeta)
        z[f <= 1e-6 * max(float(f.max(initial=0.0)), 1e-300)] = 0.0
        return z

    def reduced_matrix(self, Mr, Kr) -> np.ndarray:
        """``Dr = Mr Psi diag(2 zeta w) Psi^T Mr`` from the body's own modes (``Psi^T Mr Psi = I``)."""
        from .linalg.eigen import dense_eigenmodes

        lam, psi = dense_eigenmodes(np.asarray(Kr), np.asarray(Mr))
        if lam.size < Mr.shape[0]:
            raise OptionError("modal damping needs a reduced mass matrix that is positive definite")
        w = np.sqrt(np.maximum(lam, 0.0))
        f = w / (2 * np.pi)
        G = Mr @ psi
        D = (G * (2 * self.ratios(f) * w)) @ G.T
        return (D + D.T) / 2


def modal_damping(zeta, band) -> ModalDamping:
    """The :class:`ModalDamping` of ratio ``zeta`` (in ``[0, 1)``); ``band`` (Hz) places its Rayleigh realization."""
    r = band_matched(zeta, band, name="modal_damping")
    return ModalDamping(r.alpha, r.beta, zeta=r.zeta, band=r.band)


#: ``type`` of the stored form -> class
KINDS: dict[str, type] = {c.kind: c for c in (NoDamping, GivenDamping, Rayleigh, ModalDamping)}


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


def describe_damping(damping: Damping) -> str:
    """The damping in words: ``none``, ``Rayleigh alpha 0 1/s, beta 1e-05 s``, ``modal damping 0.01 ...``,
    ``damping matrix given with the model``."""
    if isinstance(damping, ModalDamping):
        return (f"modal damping {damping.zeta:g} in every mode (sparse realization: Rayleigh matched at "
                f"{damping.band[0]:g} and {damping.band[1]:g} Hz)")
    if isinstance(damping, Rayleigh):
        text = f"Rayleigh alpha {damping.alpha:g} 1/s, beta {damping.beta:g} s"
        zeta = getattr(damping, "zeta", None)
        return text + (f" (ratio {zeta:g} at {damping.band[0]:g} and {damping.band[1]:g} Hz)"
                       if zeta is not None else "")
    if isinstance(damping, GivenDamping):
        return "damping matrix given with the model"
    return "none"
