"""``flexmor ui``: the local web application (:mod:`flexmor.ui.server`)."""

from .server import MAX_BODY, MAX_CONNECTIONS, TIMEOUT, App, Workspace, make_server

__all__ = ["App", "Workspace", "make_server", "MAX_BODY", "MAX_CONNECTIONS", "TIMEOUT"]
