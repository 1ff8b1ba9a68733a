"""`magna studio`: design worlds and missions, and run, watch and command a mission, in the browser.

    magna studio [--port 8090] [--bind 127.0.0.1] [--search-path DIR ...] [--data-root DIR]

It serves the page on this machine (127.0.0.1 unless --bind says otherwise) and prints its address;
open it in a browser. Every asset is installed by `make setup`; nothing is fetched from the internet.
The page opens the project's worlds and missions, those under --search-path (a folder laid out like
ROS-MAGNA's Code/JSONs) or any file; it starts `magna run` on what it holds, and a bridge node
(`rosrun magna_studio bridge`) to watch and command the running mission. Ctrl-C ends the studio and
anything it started.
"""
from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from magna_common.cli_vocabulary import add_search_path
from magna_common.errors import UsageError
from magna_common.storage_tree import DEFAULT_DATA_ROOT

HELP = "the studio: design worlds and missions, and run, watch and command a mission, in the browser"
DEFAULT_PORT = 8090

_EPILOG = """\
examples:
  ./magna studio          # then open http://127.0.0.1:8090/ in a browser [background]
  ./magna studio --search-path ../shared/ros_magna_corpus --port 8091   # [synopsis]
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = __doc__
    parser.epilog = _EPILOG
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, metavar="PORT",
                        help="the port to serve on (default %(default)s; 0: a free one, printed)")
    parser.add_argument("--bind", default="127.0.0.1", metavar="ADDRESS",
                        help="the address to serve on (default %(default)s: this machine only; 0.0.0.0 opens the "
                             "studio, and the runs it starts, to the network)")
    add_search_path(parser)
    parser.add_argument("--data-root", type=Path, default=DEFAULT_DATA_ROOT, metavar="DIR",
                        help="where runs started from the page put Simulations/ (default: ~/magna_data)")


def run(args) -> int:
    import asyncio

    from magna_common.search_path import check_search_dirs
    from magna_common.workspace import find_root
    from magna_studio.run_control import StudioRun
    from magna_studio.server import Studio, make_app, missing_assets

    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port {args.port}: give a port number 0..65535 (0: a free one)")
    missing = missing_assets()
    if missing:
        raise UsageError(missing)
    search_path = [Path(p).expanduser().resolve() for p in args.search_path]
    check_search_dirs(search_path)
    data_root = args.data_root.expanduser().resolve()

    async def serve() -> None:
        import tornado.httpserver
        import tornado.netutil

        sockets = tornado.netutil.bind_sockets(args.port, address=args.bind)
        port = sockets[0].getsockname()[1]
        shown = "127.0.0.1" if args.bind in ("0.0.0.0", "::") else args.bind
        url = f"http://{shown}:{port}/"
        hosts = {shown, "localhost", "127.0.0.1"} | ({args.bind} if args.bind not in ("0.0.0.0", "::") else set())
        studio_run = StudioRun(find_root() / "magna", data_root / "studio" / "runs", data_root, search_path,
                               origin=url.rstrip("/"))
        server = tornado.httpserver.HTTPServer(make_app(Studio(search_path, data_root, studio_run, hosts)))
        server.add_sockets(sockets)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            loop.add_signal_handler(sig, stop.set)
        print(f"studio: {url}", flush=True)  # only now: from here on, Ctrl-C ends the studio in order
        try:
            await stop.wait()
        finally:
            server.stop()
            print("studio: ending the run and the bridge it started, if any", file=sys.stderr, flush=True)
            await loop.run_in_executor(None, studio_run.close)

    try:
        asyncio.run(serve())
    except OSError as err:
        raise UsageError(f"cannot serve on {args.bind}:{args.port}: {err.strerror or err}; give another --port "
                         "(0: a free one)") from None
    return 0
