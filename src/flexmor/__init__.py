"""flexmor: model order reduction of elastic bodies for multibody simulation.

The names of a study, one import away::

    import flexmor

    model = flexmor.read("beam.sti")
    beam = flexmor.System(model, inputs=["TIP:y"], band=(10, 3000))
    body = beam.reduce("krylov", 8)
    print(beam.judge(body).band_error)

Every name here lives in a module of its own (listed in ``__all__`` below with its home);
``flexmor.io``, ``flexmor.reduction`` ... are the subpackages behind them.
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
