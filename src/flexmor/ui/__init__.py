"""``flexmor ui``: the local web application (:mod:`flexmor.ui.server`)."""

from .server import App, Workspace, make_server

__all__ = ["App", "Workspace", "make_server"]
