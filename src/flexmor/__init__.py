"""flexmor: model order reduction of elastic bodies for multibody simulation.

The names of a study, one import away::

    import flexmor

    model = flexmor.read("beam.sti")
    beam = flexmor.System(model, inputs=["TIP:y"], band=(10, 3000))
    body = beam.reduce("krylov", 8)
    print(beam.judge(body).band_error)

Every name of ``__all__`` with its home, the module to read (and import) it from::

    __version__                   flexmor._version
    io                            flexmor.io
    read, read_body, export       flexmor.io
    state_space                   flexmor.io.statespace
    System                        flexmor.study
    make_ports                    flexmor.ports
    project                       flexmor.projection
    reduce                        flexmor.reduction
    simulate                      flexmor.dynamics.time
    FullResponse, ErrorMeasures   flexmor.analysis.compare
    FlexmorError, ReadError, ModelError, PortError, SolverError, ConvergenceError, OptionError,
    FlexmorWarning                flexmor.errors

The full FRF a study judges against is cached on disk (``~/.cache/flexmor`` by default, bounded,
:mod:`flexmor.analysis.cache` says where, how large and how to turn it off).
"""

from . import io
from ._version import __version__
from .analysis.compare import ErrorMeasures, FullResponse
from .dynamics.time import simulate
from .errors import (
    ConvergenceError,
    FlexmorError,
    FlexmorWarning,
    ModelError,
    OptionError,
    PortError,
    ReadError,
    SolverError,
)
from .io import export, read, read_body
from .io.statespace import state_space
from .ports import make_ports
from .projection import project
from .reduction import reduce
from .study import System

__all__ = [
    "__version__",
    # reading and writing (flexmor.io)
    "io", "read", "read_body", "export", "state_space",
    # a study (flexmor.study) and its steps
    "System", "make_ports", "project", "reduce", "simulate",
    # judging (flexmor.analysis.compare)
    "FullResponse", "ErrorMeasures",
    # errors (flexmor.errors)
    "FlexmorError", "ReadError", "ModelError", "PortError", "SolverError", "ConvergenceError", "OptionError",
    "FlexmorWarning",
]
