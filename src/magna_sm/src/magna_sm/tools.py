"""The command-line tools of magna_sm (`rosrun magna_sm draw|viewer|demo`), as importable functions."""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from magna_common.cli_vocabulary import OutputExists, add_force, add_output, check_output
from magna_sm.container import Container
from magna_sm.draw import FORMATS, DrawError, draw

DRAW_EXAMPLES = """\
examples:
  rosrun magna_sm draw magna_sm.examples:filmed_delivery -o /tmp/filmed_delivery.png --force
  rosrun magna_sm draw magna_sm.examples:filmed_delivery -o /tmp/filmed_delivery.svg --title "filmed delivery" --force
"""

VIEWER_EXAMPLES = """\
examples:
  roslaunch magna_sm demo.launch   # an example machine with introspection (and a master) [background]
  rosrun magna_sm viewer demo -o /tmp/live.png --force --once --timeout 60 --no-window
"""


def load_machine(target: str) -> Container:
    """`package.module:callable` -> the container the callable builds."""
    module_name, _, attribute = target.partition(":")
    if not module_name or not attribute:
        raise SystemExit(f"draw: TARGET must look like 'package.module:function', got '{target}'")
    try:
        factory = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as error:
        raise SystemExit(f"draw: cannot load '{target}': {error}") from None
    machine = factory()
    if not isinstance(machine, Container):
        raise SystemExit(f"draw: '{target}' returned {type(machine).__name__}, not a state-machine container")
    return machine


def draw_main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="rosrun magna_sm draw",
        description="Draw a state machine to PNG, SVG, PDF or DOT with graphviz: containers as clusters,\n"
                    "or drawn flat when graphviz cannot lay the clusters out. An existing FILE is\n"
                    "replaced only with --force.",
        epilog=DRAW_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("target", metavar="TARGET",
                        help="a Python callable building the machine, e.g. magna_sm.examples:filmed_delivery")
    add_output(parser, required=True, metavar="FILE",
               help=f"picture file; format from its suffix ({', '.join('.' + f for f in FORMATS)})")
    add_force(parser, help="replace FILE if it exists")
    parser.add_argument("--title", default="", help="title written above the picture")
    parser.add_argument("--no-check", action="store_true", help="draw even if the machine does not validate")
    args = parser.parse_args(argv)
    try:
        check_output(args.output, args.force)
    except OutputExists as error:
        print(f"draw: {error}", file=sys.stderr)
        return 2
    machine = load_machine(args.target)
    if not args.no_check:
        machine.check()
    try:
        print(draw(machine, args.output, title=args.title))
    except DrawError as error:
        print(f"draw: {error}", file=sys.stderr)
        return 2
    return 0


def viewer_main(argv: list[str] | None = None) -> int:
    import rospy

    from magna_common.ros_names import SM_ROOT
    from magna_sm.introspection import run_viewer

    parser = argparse.ArgumentParser(
        prog="rosrun magna_sm viewer",
        description="Redraw a running machine from its introspection topics into an image file, and in a\n"
                    "window when a display exists. An existing FILE is replaced only with --force.",
        epilog=VIEWER_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("server", help="introspection server name (topics <namespace>/<server>/structure|status)")
    add_output(parser, default=Path("state_machine.png"), metavar="FILE",
               help="image file kept up to date (default: %(default)s)")
    add_force(parser, help="replace FILE if it exists when the viewer starts")
    parser.add_argument("--namespace", default=SM_ROOT, help="topic namespace (default: %(default)s)")
    parser.add_argument("--period", type=float, default=0.5, help="least seconds between redraws")
    parser.add_argument("--once", action="store_true", help="draw once the machine is seen, then exit")
    parser.add_argument("--timeout", type=float, default=10.0, help="with --once: seconds to wait for the machine")
    parser.add_argument("--no-window", action="store_true",
                        help="never open a window (by default one opens when a display exists)")
    args = parser.parse_args(rospy.myargv(argv if argv is not None else sys.argv)[1:])
    try:
        check_output(args.output, args.force)
    except OutputExists as error:
        print(f"viewer: {error}", file=sys.stderr)
        return 2
    rospy.init_node("magna_sm_viewer", anonymous=True)
    window = not args.no_window and bool(os.environ.get("DISPLAY"))
    return run_viewer(args.server, args.output, args.namespace, args.period, args.once, args.timeout, window)


def demo_main(argv: list[str] | None = None) -> int:
    import rospy

    from magna_sm.examples import filmed_delivery
    from magna_sm.introspection import IntrospectionServer

    parser = argparse.ArgumentParser(
        prog="rosrun magna_sm demo",
        description="Run the example filmed-delivery machine slowly, with introspection, for the viewer.")
    parser.add_argument("--step", type=float, default=1.0, help="seconds each state waits (default: %(default)s)")
    parser.add_argument("--name", default="demo", help="introspection server name (default: %(default)s)")
    parser.add_argument("--repeat", type=int, default=1, help="runs of the machine (default: %(default)s)")
    args = parser.parse_args(rospy.myargv(argv if argv is not None else sys.argv)[1:])
    rospy.init_node("magna_sm_demo", anonymous=True)
    machine = filmed_delivery(step=args.step)
    server = IntrospectionServer(args.name, machine, heartbeat=min(1.0, args.step)).start()
    rospy.on_shutdown(machine.request_preempt)
    try:
        for _ in range(args.repeat):
            outcome = machine.execute()
            rospy.loginfo(f"magna_sm demo: mission ended with '{outcome}'")
            if rospy.is_shutdown():
                break
    finally:
        server.stop()
    return 0
