"""``skillcompose view``: the web viewer's subcommand (registered through the runtime CLI's
hook for other packages; the runtime's heavy modules and the web libraries load only when
the command runs, so ``skillcompose --help`` stays light)."""

from __future__ import annotations

import argparse
import errno
import ipaddress
import socket
import sys
from pathlib import Path
from typing import Any

from skillcompose.arguments import UsageError, module_or_file, number, setting, whole

from .trust import REFRESH_S

__all__ = ["DEFAULT_PORT", "handle", "register_cli"]

DEFAULT_PORT = 8765
DESCRIPTION = """\
Start a local web app that shows runs, FSA files, replays and live FSAs:

  Runs    every run directory (run.json) under DIR: task, settings, status, generations,
          best fitness, fresh-episode success; the fitness history, updated as it is written
  FSA     an FSA file as a graph (skills, parameters with units and ranges, outcomes,
          start, terminals, unreachable and trap states) beside its YAML and its problems
  Replay  one episode (task, settings, seed) stepped forward and back; the PR2 in 3D on a
          kinematic task
  Live    FSAs that publish their state as they run (skillcompose.view.live)

It listens on 127.0.0.1 unless --host says otherwise; Ctrl-C stops it. Another address
(beyond this machine) needs --allow-remote, and then every request needs the random access
token printed in the address (as Jupyter's); --token asks for one on 127.0.0.1 too.
"""


def _host(text: str) -> str:
    if text == "localhost":
        return "127.0.0.1"
    try:
        return str(ipaddress.ip_address(text))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not an IP address; give one such as 127.0.0.1 (this machine only)"
        ) from None


def register_cli(subparsers: Any) -> None:
    """Add ``view`` to the ``skillcompose`` command."""
    p = subparsers.add_parser(
        "view", help="web viewer: runs, FSA graphs, replays, live FSAs",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("path", nargs="?", default=".", metavar="DIR|FILE",
                   help="a folder of runs and FSA files, or one FSA file (default: .)")
    p.add_argument("--task", type=module_or_file, metavar="TASK",
                   help="a task module: units and ranges of parameters, checks, replays")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   dest="settings", type=setting, help="a task setting; repeatable")
    p.add_argument("--port", type=whole(1, 65535), default=DEFAULT_PORT,
                   help=f"port to listen on (default {DEFAULT_PORT})")
    p.add_argument("--host", type=_host, default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1, this machine only; "
                   "another needs --allow-remote)")
    p.add_argument("--allow-remote", action="store_true",
                   help="allow a --host beyond this machine (such as 0.0.0.0): anyone who "
                   "reaches it with the printed token sees what the viewer shows")
    p.add_argument("--refresh", type=number(0.1, 3600.0), default=REFRESH_S,
                   metavar="SECONDS",
                   help="how often the runs page reads the run directories again and the "
                   f"live page looks for new live files (default {REFRESH_S:g} s; "
                   "longer for a folder of many runs on a slow disk)")
    p.add_argument("--token", action="store_true",
                   help="require a random access token (printed in the address) on "
                   "127.0.0.1 too; always required beyond this machine")
    p.set_defaults(func=handle)


def serving(host: str, allow_remote: bool, token: bool) -> tuple[bool, bool]:
    """Whether the viewer listens beyond this machine, and whether it requires a token;
    raises :class:`UsageError` for an address beyond it without ``--allow-remote``."""
    remote = not ipaddress.ip_address(host).is_loopback
    if remote and not allow_remote:
        raise UsageError(f"--host {host}: an address beyond this machine lets others reach "
                         "the viewer; add --allow-remote to serve it there (an access token "
                         "is then required), or leave out --host to serve 127.0.0.1")
    return remote, remote or token


def _check_port(host: str, port: int) -> None:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            why = "is in use" if exc.errno == errno.EADDRINUSE else \
                f"cannot be opened ({exc.strerror})"
            raise UsageError(f"--port {port}: {host}:{port} {why}; choose another --port")\
                from None


def handle(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if not path.exists():
        raise UsageError(f"{args.path}: no such file or folder; give a folder of runs or an "
                         "FSA file")
    file = path if path.is_file() else None
    root = (path.parent if file is not None else path).resolve()
    from skillcompose.task import parse_settings  # the runtime loads here, not for --help

    settings = parse_settings(args.settings)
    remote, needs_token = serving(args.host, args.allow_remote, args.token)
    _check_port(args.host, args.port)

    from nicegui import ui  # the web libraries load here, not when the parser is built

    from .app import ViewerConfig, build
    from .guard import new_token

    token = new_token() if needs_token else None
    label = str(path.parent if file is not None else path)
    build(ViewerConfig(root=root, file=file.resolve() if file else None, task=args.task,
                       settings=settings, label=label, token=token, remote=remote,
                       port=args.port, refresh=args.refresh))
    url_host = f"[{args.host}]" if ":" in args.host else args.host
    page = ("/fsa" if file is not None else "/") + (f"?token={token}" if token else "")
    if remote:
        print(f"skillcompose view: warning: serving on {args.host}, beyond this machine: "
              "anyone who can reach this address and has the token below sees every run and "
              "file the viewer shows; keep the token to yourself, and stop the viewer "
              "(Ctrl-C) when done", file=sys.stderr, flush=True)
    print(f"skillcompose view: serving {label} on http://{url_host}:{args.port}{page} "
          "(Ctrl-C stops it)", flush=True)
    ui.run(host=args.host, port=args.port, reload=False, show=False,
           title="skillcompose view", show_welcome_message=False, dark=False,
           uvicorn_logging_level="warning", favicon="🤖")
    print("skillcompose view: stopped", file=sys.stderr)
    return 0
