"""One preparation of a full model for a study: read, mesh, units, node selections, preload, couplings, damping.

:func:`prepare` is the one step between an FE file and the model a study reduces and judges;
:class:`flexmor.System` takes its options as keywords, and every command of the command line maps
its flags onto it (``--format``, ``--mesh``, ``--units``, ``--select``, ``--preload``,
``--material``, ``--interface``, ``--rayleigh`` / ``--modal-damping`` / ``--band-rayleigh``)::

    from flexmor.prepare import prepare

    done = prepare("deck.inp", units="mm-t-s", select=["TIP=box:990,0,0,1000,100,100"],
                   preload=["TIP:x=1000"], couplings=["TIP@rbe2"], damping={"rayleigh": (0, 1e-6)})
    done.model, done.as_read, done.unloaded

The order is fixed: read (``format``), add the mesh, convert to SI (``units``), add node sets
(``select``, in order), stiffen by the preload (``preload``, ``material``), couple the interfaces
(``couplings``), add the damping. Under ``mpirun`` with the ``petsc`` backend rank 0 reads and
prepares, and every rank gets its rows (:func:`flexmor.models.distributed.read_on_root`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from os import PathLike
from typing import Any

from .damping import Damping, NoDamping
from .errors import ModelError, OptionError
from .linalg.context import DISTRIBUTED, SolverContext, step
from .model import FEModel

__all__ = ["prepare", "Prepared", "as_damping", "PREPARATION", "DAMPING_KEYS"]

#: The keywords of :func:`prepare` that say how the file becomes the model (those a study file records
#: under ``[model]``, beside the file and its checksum).
PREPARATION = ("format", "mesh", "units", "select", "preload", "material")

#: The dict forms of ``damping`` (the keywords of :func:`flexmor.workflow.damping_of`).
DAMPING_KEYS = ("rayleigh", "modal_damping", "band_rayleigh")


@dataclasses.dataclass
class Prepared:
    """What :func:`prepare` made of a file.

    Attributes
    ----------
    model : FEModel
        The model of the study: in SI, its node sets, preloaded, coupled, damped.
    as_read : FEModel
        The same before the couplings and the damping (for the couplings' frequencies and stresses).
    unloaded : FEModel or None
        The coupled model without the preload (None without a preload).
    couplings : list of str
        The coupling SPECs applied.
    nearest : list of dict
        The node each ``NAME=nearest:X,Y,Z`` selection chose (:func:`flexmor.selection.nearest_report`).
    check : object
        ``check(model)`` of the model as read, units and node sets applied (None without ``check``).
    seconds : float
        Wall time of the preparation.
    """

    model: FEModel
    as_read: FEModel
    unloaded: FEModel | None
    couplings: list
    nearest: list
    check: Any
    seconds: float


def as_damping(damping, band=None) -> Damping | None:
    """``damping`` as a :class:`~flexmor.damping.Damping`: a Damping as it is, a dict with one of
    :data:`DAMPING_KEYS` through :func:`flexmor.workflow.damping_of` (modal and band-matched damping
    over ``band``), None as None (the model's own damping)."""
    from .options import Band
    from .workflow import damping_of

    if damping is None or isinstance(damping, Damping):
        return damping
    forms = "{'rayleigh': (alpha, beta)}, {'modal_damping': zeta} or {'band_rayleigh': zeta}"
    if not isinstance(damping, dict):
        raise OptionError(f"damping must be a flexmor.damping object (Rayleigh(alpha, beta), ...) or a dict "
                          f"{forms}, got {type(damping).__name__} {damping!r}", params=("damping",))
    unknown = sorted(set(damping) - set(DAMPING_KEYS))
    if unknown:
        raise OptionError(f"damping {damping!r}: unknown key(s) {', '.join(map(repr, unknown))}; give {forms}",
                          params=("damping",))
    return damping_of(**{"band": Band.of(band), **damping})


def _texts(value, name: str) -> list[str]:
    """A list of SPEC texts; a lone string is refused (``["TIP=..."]``, not ``"TIP=..."``)."""
    if value is None:
        return []
    if isinstance(value, str | bytes):
        raise OptionError(f"{name} must be a list of texts, e.g. [{value!r}], got the string {value!r}",
                          params=(name,))
    return [str(v) for v in value]


def prepare(model, *, format: str | None = None, mesh=None, units=None, select: Sequence[str] = (),
            preload: Sequence[str] = (), material=None, couplings: Sequence[str] = (), damping=None, band=None,
            check: Callable | None = None, solver: SolverContext | None = None,
            progress: Callable | None = None) -> Prepared:
    """The model of a study, from its file (or an :class:`~flexmor.model.FEModel` as read).

    Parameters
    ----------
    model : path-like or FEModel
        The FE file (:func:`flexmor.io.read`) or a model as read.
    format : str, optional
        The file's format when its name does not say (:data:`flexmor.io.FORMATS`).
    mesh : path-like, optional
        A mesh file giving the nodes and elements (:func:`flexmor.io.meshio_mesh.with_mesh`).
    units : str, optional
        The unit system the file's numbers are in (:data:`flexmor.units.SYSTEMS`); the model is converted to SI.
    select : list of str
        ``NAME=KIND:NUMBERS`` node selections (:func:`flexmor.selection.with_selections`), in SI.
    preload : list of str
        Preload SPECs (:func:`flexmor.preload.with_preload`): K about the static equilibrium.
    material : (E, nu[, rho]), optional
        The material of the preload's stresses in place of the deck's (and of the stress modes of
        the bodies: :attr:`flexmor.System.material`).
    couplings : list of str
        ``SET@rbe2`` / ``SET@rbe3`` couplings (:func:`flexmor.workflow.coupling_specs` of the
        interfaces and ports).
    damping : Damping or dict, optional
        :func:`as_damping`; None keeps the model's own.
    band : (float, float), optional
        The band modal and band-matched damping are matched over (default the default band).
    check : callable, optional
        Run on the model as read (units and node sets applied), e.g. the geometry check; its result
        is :attr:`Prepared.check`.
    solver : SolverContext, optional
        With the ``petsc`` backend under ``mpirun``: rank 0 reads and prepares, each rank gets its rows.
    progress : callable, optional
        Shown the reading as one step.
    """
    select, preload = _texts(select, "select"), _texts(preload, "preload")
    couplings = _texts(couplings, "couplings")
    if model is None or not isinstance(model, str | PathLike | FEModel):
        raise ModelError(f"a model is an FE model or the path of its file, got {type(model).__name__}",
                         params=("model",))
    damping = as_damping(damping, band)
    if isinstance(model, FEModel) and (format is not None or mesh is not None or units is not None):
        given = [n for n, v in (("format", format), ("mesh", mesh), ("units", units)) if v is not None]
        raise OptionError(f"{', '.join(given)} say how a file is read; the model was given read (give its path)",
                          params=tuple(given))
    keep: dict = {"uncoupled": None, "unloaded": None, "nearest": [], "check": None}

    def load() -> FEModel:
        from .units import to_si
        from .workflow import prepare_model

        out = model
        if not isinstance(out, FEModel):
            from .io import read

            out = read(out, format=format)
        if mesh is not None:
            from .io.meshio_mesh import with_mesh

            out = with_mesh(out, mesh)
        out = to_si(out, units)
        if select:
            from .selection import nearest_report, with_selections

            out = with_selections(out, select)
            keep["nearest"] = nearest_report(out, select)
        if check is not None:
            keep["check"] = check(out)
        unloaded = out
        if preload:  # K about the preloaded equilibrium
            from .preload import with_preload

            out = with_preload(out, preload, material=material)
        keep["uncoupled"] = out
        if preload:
            keep["unloaded"] = prepare_model(unloaded, couplings)
        return prepare_model(out, couplings)

    t0 = time.perf_counter()
    label = str(model.source or model.name) if isinstance(model, FEModel) else str(model)
    if solver is not None and solver.backend in DISTRIBUTED:  # under mpirun: rank 0 reads, each rank its rows
        from .models.distributed import read_on_root

        done = read_on_root(load, keep)
    else:
        with step(progress, f"read {label}"):
            done = load()
    if damping is not None and not isinstance(damping, NoDamping):
        done = done.with_damping(damping)
    return Prepared(model=done, as_read=keep["uncoupled"], unloaded=keep["unloaded"], couplings=couplings,
                    nearest=keep["nearest"], check=keep["check"], seconds=time.perf_counter() - t0)
