"""``hsr view``: the live page in the browser."""

from __future__ import annotations

import sys

from .options import CliError, add_up_axis


def add_parser(sub) -> None:
    from ..scene.builtin import SCENES

    v = sub.add_parser("view", help="an interactive page in the browser: every algorithm and "
                       "switch, live", description="Serve a local page that renders MODEL "
                       "(or the built-in scenes) with hsr as you drag, with every control.")
    v.add_argument("models", nargs="*", metavar="MODEL", help="mesh files to show (the "
                   "built-in scenes are always there)")
    v.add_argument("--scene", choices=list(SCENES), help="built-in scene shown first "
                   "(default: the first MODEL, else cubes)")
    v.add_argument("--host", default="127.0.0.1", help="address to listen on; anything but "
                   "127.0.0.1 / localhost lets other machines in")
    v.add_argument("--port", type=int, default=8765, help="port to listen on")
    v.add_argument("--no-browser", action="store_true", help="do not open the browser")
    add_up_axis(v, "the orbit turns about it")


def run(args) -> int:
    import socket

    from ..viewer import serve

    if not 1 <= args.port <= 65535:
        raise CliError(f"--port must be in 1..65535, got {args.port}")
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"hsr: warning: listening on {args.host}: other machines can reach this "
              f"viewer", file=sys.stderr)
    try:  # a clear error now rather than a server that fails to start
        with socket.create_server((args.host, args.port)):
            pass
    except OSError as exc:
        raise CliError(f"cannot listen on {args.host}:{args.port} ({exc.strerror or exc})") \
            from None
    first = args.scene if args.scene else (None if args.models else "cubes")
    try:
        serve(args.models, args.host, args.port, not args.no_browser, first=first,
              up_axis=args.up_axis or "auto")
    except KeyboardInterrupt:
        pass
    return 0
