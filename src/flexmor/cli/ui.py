"""``flexmor ui [FOLDER] [--port PORT] [--no-browser]``: start the local web application."""

from __future__ import annotations

import webbrowser

__all__ = ["add_ui_parser", "cmd_ui"]


def add_ui_parser(sub) -> None:
    """Register the ``ui`` subcommand on the subparsers ``sub``."""
    p = sub.add_parser("ui", help="local web application: open a model, pick nodes in 3D, reduce, compare, export",
                       description="Serve the flexmor web application on 127.0.0.1 for one user; files are "
                                   "read and written only inside FOLDER.")
    p.add_argument("folder", nargs="?", default=".", help="working folder (default: the current one)")
    p.add_argument("--port", type=int, default=8765, help="TCP port on 127.0.0.1 (default 8765; 0: any free port)")
    p.add_argument("--no-browser", action="store_true", help="print the address instead of opening a browser")
    p.set_defaults(func=cmd_ui)


def cmd_ui(args) -> int:
    """``flexmor ui``: serve the web app on 127.0.0.1 until interrupted; returns the exit code."""
    from ..ui import make_server

    # jobs run the command line's own main; a SIGTERM whose exception was lost still ends the serving
    server, app, url = make_server(args.folder, args.main, args.port, poll=args.check_terminated)
    print(f"flexmor ui: serving {app.ws.root} at {url}  (Ctrl-C stops)", flush=True)
    if not args.no_browser:
        webbrowser.open(url)
    try:
        server.serve_forever()
    finally:
        server.server_close()
    return 0
