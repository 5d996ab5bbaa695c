"""Unit systems of FE files and their conversion to SI.

flexmor computes in SI (m, kg, s, N): frequencies in Hz, times in s, Rayleigh ``alpha`` in 1/s
and ``beta`` in s. An FE file in another consistent system (``mm-t-s``, the usual one of
CalculiX and Abaqus decks in millimetres) is converted on reading when its system is named
(``read(path, units="mm-t-s")``, ``--units mm-t-s``); a file whose system is not named is taken
**as given**: its numbers are used as they are, nothing is guessed (:data:`AS_GIVEN`).

A system is given by the SI value of its length, mass and time units; force, stress, density
and energy follow (:class:`UnitSystem`). The systems of :data:`SYSTEMS`:

==========  ======  ==============  =====  =====  ======  ==============
name        length  mass            time   force  stress  density
==========  ======  ==============  =====  =====  ======  ==============
SI          m       kg              s      N      Pa      kg/m^3
mm-t-s      mm      t               s      N      MPa     t/mm^3
mm-kg-ms    mm      kg              ms     kN     GPa     kg/mm^3
mm-g-ms     mm      g               ms     N      MPa     g/mm^3
in-lbf-s    in      lbf s^2/in      s      lbf    psi     lbf s^2/in^4
==========  ======  ==============  =====  =====  ======  ==============

(``m-kg-s`` is another name of ``SI``.)

The conversion of a model (:func:`to_si`)
    A translational equation is a displacement in the length unit ``L`` and its load a force
    ``F``; a rotational equation is an angle (rad, no unit) and its load a moment ``F L``. With
    the per-equation length ``s_i`` (``L`` for x y z, 1 for rx ry rz) and the energy unit
    ``E = F L``, ``T = diag(1 / s_i)`` and the time unit ``t``::

        K_SI = E T K T,    M_SI = E t^2 T M T,    D_SI = E t T D T

    so a translation-translation entry of ``K`` scales by ``F / L`` (N/mm to N/m: 1e3), a
    rotation-rotation entry by ``F L`` (N mm/rad to N m/rad: 1e-3) and a coupling entry by
    ``F``; the mass of a translation by the mass unit, a rotary inertia by ``mass L^2``.
    Rayleigh ``alpha`` (1/time) and ``beta`` (time) and the band of a modal damping (Hz of the
    file's time) are converted, node coordinates scale by ``L``. An input column of ``B`` given
    with the model is a force when it loads a translation (its rotation rows, lever arms,
    scale by ``L``), else a moment (unchanged); an output row of ``C`` likewise a displacement or
    a rotation.

A reduced body is computed in SI; exporters that can write another system
(:func:`flexmor.io.export` with ``units=``) scale each quantity by its dimension
(:meth:`UnitSystem.from_si`), the modal coordinates unchanged.
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .damping import BandMatched, Damping, Rayleigh
from .errors import ModelError, OptionError
from .linalg.distributed import is_partitioned
from .model import DIRECTIONS

__all__ = ["AS_GIVEN", "SI", "SYSTEMS", "UnitSystem", "describe_units", "dof_lengths", "export_units", "frf_unit",
           "port_kind", "to_si", "unit_system"]

#: What a model or body whose file states no unit system is: its numbers as given.
AS_GIVEN = "as given (the file states no unit system; name it with units=...)"


@dataclass(frozen=True)
class UnitSystem:
    """A consistent unit system: the SI values of its length, mass and time units and their names.

    Attributes
    ----------
    name : str
        Canonical name (``SI``, ``mm-t-s`` ...).
    length, mass, time : float
        One unit in m, kg and s.
    length_unit, mass_unit, time_unit, force_unit, stress_unit, density_unit : str
        The names of the units, for headers and messages.
    aliases : tuple of str
        Other names of the system (lower case).
    """

    name: str
    length: float
    mass: float
    time: float
    length_unit: str
    mass_unit: str
    time_unit: str
    force_unit: str
    stress_unit: str
    density_unit: str
    aliases: tuple = ()

    @property
    def force(self) -> float:
        """One force unit in N (``mass length / time^2``)."""
        return self.mass * self.length / self.time**2

    @property
    def stress(self) -> float:
        """One stress unit in Pa (``force / length^2``)."""
        return self.force / self.length**2

    @property
    def density(self) -> float:
        """One density unit in kg/m^3 (``mass / length^3``)."""
        return self.mass / self.length**3

    @property
    def energy(self) -> float:
        """One energy (and moment) unit in J = N m (``force length``)."""
        return self.force * self.length

    @property
    def is_si(self) -> bool:
        """Whether every unit is the SI one."""
        return self.length == 1.0 and self.mass == 1.0 and self.time == 1.0

    def factor(self, length: float = 0, mass: float = 0, time: float = 0) -> float:
        """SI value of one unit of the quantity of dimension ``length^a mass^b time^c``."""
        return self.length**length * self.mass**mass * self.time**time

    def from_si(self, value, length: float = 0, mass: float = 0, time: float = 0):
        """``value`` (SI) of dimension ``length^a mass^b time^c`` in this system."""
        return np.asarray(value, dtype=float) / self.factor(length, mass, time)

    def describe(self) -> str:
        """``mm-t-s (length mm, mass t, time s, force N, stress MPa, density t/mm^3)``."""
        return (f"{self.name} (length {self.length_unit}, mass {self.mass_unit}, time {self.time_unit}, force "
                f"{self.force_unit}, stress {self.stress_unit}, density {self.density_unit})")


_LBF = 4.4482216152605  # N
_IN = 0.0254  # m

#: SI, the system flexmor computes in.
SI = UnitSystem("SI", 1.0, 1.0, 1.0, "m", "kg", "s", "N", "Pa", "kg/m^3", aliases=("m-kg-s",))

#: The unit systems by canonical name.
SYSTEMS: dict[str, UnitSystem] = {s.name: s for s in (
    SI,
    UnitSystem("mm-t-s", 1e-3, 1e3, 1.0, "mm", "t", "s", "N", "MPa", "t/mm^3"),
    UnitSystem("mm-kg-ms", 1e-3, 1.0, 1e-3, "mm", "kg", "ms", "kN", "GPa", "kg/mm^3"),
    UnitSystem("mm-g-ms", 1e-3, 1e-3, 1e-3, "mm", "g", "ms", "N", "MPa", "g/mm^3"),
    UnitSystem("in-lbf-s", _IN, _LBF / _IN, 1.0, "in", "lbf s^2/in", "s", "lbf", "psi", "lbf s^2/in^4"),
)}


def _key(text: str) -> str:
    return "-".join(str(text).strip().lower().replace("_", "-").replace("/", "-").split())


def unit_system(name, *, param: str = "units") -> UnitSystem:
    """The :class:`UnitSystem` called ``name`` (case-insensitive; an alias such as ``m-kg-s`` allowed).

    Parameters
    ----------
    name : str or UnitSystem
    param : str
        The parameter the error names.

    Raises
    ------
    OptionError
        Naming ``param``: an unknown name, with the closest one ("did you mean") and the list.
    """
    if isinstance(name, UnitSystem):
        return name
    key = _key(name)
    names = {s.name.lower(): s for s in SYSTEMS.values()} | {a: s for s in SYSTEMS.values() for a in s.aliases}
    if key in names:
        return names[key]
    close = difflib.get_close_matches(key, list(names), n=1, cutoff=0.5)
    hint = f"did you mean {names[close[0]].name!r}? " if close else ""
    raise OptionError(f"{param}={name!r} is not a unit system flexmor knows; {hint}choose one of: "
                      f"{', '.join(SYSTEMS)} (m-kg-s is SI)", params=(param,))


def describe_units(units) -> str:
    """A model's or body's ``units`` in words: the system with its units, or :data:`AS_GIVEN` for None."""
    if units is None:
        return AS_GIVEN
    try:
        system = unit_system(units)
    except OptionError:
        return str(units)
    return system.describe() + ("" if system.is_si else ", converted to SI on reading")


def export_units(body, units) -> UnitSystem:
    """The unit system ``units`` a reduced body is written in, checked against the body.

    Raises
    ------
    OptionError
        An unknown system (naming ``units``).
    ModelError
        A system other than SI for a body whose model was read as given (``body.units`` None):
        the units of its numbers are not known.
    """
    system = unit_system(units)
    if getattr(body, "units", None) is None and not system.is_si:
        raise ModelError(f"the body was reduced from a model read as given (its unit system not named), so its "
                         f"numbers cannot be written in {system.name}; reduce it from the model read with units "
                         "named (e.g. SI)", params=("units",))
    return system


def dof_lengths(dofs, system) -> np.ndarray:
    """The length of each equation in m: the length unit of ``system`` at x y z, 1 at rx ry rz (rad).

    Parameters
    ----------
    dofs : ndarray of int, shape (n_dof, 2)
        Equation map (node id, direction code 1..6).
    system : UnitSystem or str
    """
    system = unit_system(system)
    d = np.asarray(dofs, dtype=np.int64).reshape(-1, 2)[:, 1]
    return np.where(d <= 3, system.length, 1.0)


def _scaled(A, d, factor: float):
    """``factor diag(d) A diag(d)`` of a sparse matrix, exactly symmetric for a symmetric ``A`` (None stays None)."""
    if A is None:
        return None
    A = sp.csr_matrix(A, copy=True)
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    A.data = A.data * (d[rows] * d[A.indices] * factor)
    return A


def _port_scale(P, rot_rows: np.ndarray, length: float, axis: int):
    """``B`` (``axis`` 0: equations are rows) or ``C`` (``axis`` 1) given with a model, to SI: a port that
    touches a translation is a force (a displacement), so its entries at rotations (lever arms) scale by
    ``length``; a port on rotations only is a moment (a rotation) and stays."""
    if P is None:
        return None
    P = sp.csr_matrix(P).tocoo()
    eq = P.row if axis == 0 else P.col
    port = P.col if axis == 0 else P.row
    trans = np.zeros(P.shape[1 - axis], dtype=bool)
    trans[port[~rot_rows[eq] & (P.data != 0)]] = True
    data = np.where(rot_rows[eq] & trans[port], P.data * length, P.data)
    return sp.csr_matrix((data, (P.row, P.col)), shape=P.shape)


def _damping_si(damping: Damping, system: UnitSystem) -> Damping:
    """Rayleigh ``alpha`` (1/time), ``beta`` (time) and a band (Hz of the file's time) in SI."""
    if not isinstance(damping, Rayleigh):
        return damping
    t = system.time
    changes = {"alpha": damping.alpha / t, "beta": damping.beta * t}
    if isinstance(damping, BandMatched):
        changes["band"] = tuple(float(f) / t for f in damping.band)
    return dataclasses.replace(damping, **changes)


def to_si(model, units):
    """``model``, read from a file in the unit system ``units``, converted to SI.

    Parameters
    ----------
    model : FEModel
        As read: its numbers in ``units``, its ``units`` None (not stated).
    units : str, UnitSystem or None
        The file's system (:data:`SYSTEMS`); None returns ``model`` as given.

    Returns
    -------
    FEModel
        ``M``, ``K``, ``D``, node coordinates, ``B``, ``C`` and the damping in SI (see the module
        docstring), its ``units`` the system's name. For ``SI`` the numbers stay and only
        ``units`` is recorded.

    Raises
    ------
    OptionError
        An unknown system.
    ModelError
        A model already converted (``units`` recorded), or a model without an equation map
        outside SI (which equations are rotations is not known).
    """
    if units is None:
        return model
    system = unit_system(units)
    where = model.source or model.name
    if model.units is not None:
        raise ModelError(f"{where} was read in {model.units} already and converted to SI; read it once with "
                         "units", params=("units",))
    out = copy.copy(model)  # every check of the model holds for the scaled one: not made again
    out.units = system.name
    if system.is_si:
        return out
    if model.dofs is None:
        raise ModelError(f"{where} has no equation map, so which equations are rotations is not known: it cannot "
                         f"be converted from {system.name}; give the nodes of its equations (mesh)",
                         params=("units", "mesh"))
    if is_partitioned(model.K):
        raise ModelError(f"{where}: a model whose rows are spread over MPI ranks cannot be converted; convert it "
                         "before it is distributed", params=("units",))
    s = dof_lengths(model.dofs, system)
    d = 1.0 / s
    E, t = system.energy, system.time
    out.K = _scaled(model.K, d, E)
    out.M = _scaled(model.M, d, E * t**2)
    out.D = _scaled(model.D, d, E * t)
    out.damping = _damping_si(model.damping, system)
    out.xyz = model.xyz * system.length
    rot = model.dofs[:, 1] > 3
    out.B = _port_scale(model.B, rot, system.length, 0)
    out.C = _port_scale(model.C, rot, system.length, 1)
    if model.elements is not None:  # materials: elasticity in stress units, density (stresses come out in SI)
        out.elements = model.elements.converted(system.stress, system.density)
    return out


def port_kind(spec) -> str | None:
    """``"translation"`` or ``"rotation"`` for a port SPEC ending in a direction (``TIP:y``,
    ``HOLE@rbe3:rx``, a compressed one ``PATH:z~2``: loads in that direction), None for a name without one
    (ports given as matrices)."""
    text = str(spec)
    if ":" not in text:
        return None
    d = text.rsplit(":", 1)[1].split("~", 1)[0].strip().lower()
    if d not in DIRECTIONS:
        return None
    return "translation" if DIRECTIONS[d] <= 3 else "rotation"


def frf_unit(output, input, system=SI) -> str:
    """The unit of the transfer function from the input port ``input`` to the output port ``output``
    (SPECs) in ``system``: ``m/N``, ``rad/N``, ``m/(N m)``, ``rad/(N m)``; ``""`` when a port names no
    direction."""
    system = unit_system(system)
    ko, ki = port_kind(output), port_kind(input)
    if ko is None or ki is None:
        return ""
    num = system.length_unit if ko == "translation" else "rad"
    den = system.force_unit if ki == "translation" else f"({system.force_unit} {system.length_unit})"
    return f"{num}/{den}"
