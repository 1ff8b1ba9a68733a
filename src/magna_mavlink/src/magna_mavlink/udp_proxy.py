"""A UDP proxy that puts a bad radio link between a MAVLink vehicle and its client.

    client  <-->  [listen socket | proxy | vehicle socket]  <-->  vehicle (--to HOST:PORT)

The client sends to the proxy's listen port; the proxy learns the client's address from the first
packet it gets there (and follows a client that comes back from another port, as PX4 does), and
forwards to the vehicle from a socket of its own, whose replies go back to the client. In both
directions it can drop a fraction of the packets (a seeded random draw per packet, one generator per
direction, so a run is repeatable), delay every packet by a fixed one-way time (in order: a FIFO, as
a single radio link keeps its packets in order), and cut the link for a span: on a schedule
(cut_at/cut_for, from start()) or on command (cut() / resume()). Packets that enter the link while it
is cut are lost; packets already on their way still arrive.

One thread serves both sockets; stop() ends it and closes every socket.
"""
from __future__ import annotations

import argparse
import math
import random
import selectors
import signal
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

TO_VEHICLE, TO_CLIENT = "to_vehicle", "to_client"
DIRECTIONS = (TO_VEHICLE, TO_CLIENT)
MAX_DATAGRAM = 65535


@dataclass
class DirectionCounters:
    received: int = 0  # packets that entered the link in this direction
    forwarded: int = 0  # packets sent on (after their delay)
    lost: int = 0  # dropped by the loss draw
    cut: int = 0  # dropped because the link was cut
    no_client: int = 0  # vehicle packets before any client had spoken (nowhere to send them)
    unsent: int = 0  # the socket refused to send them (e.g. no route)

    @property
    def dropped(self) -> int:
        return self.lost + self.cut + self.no_client + self.unsent


@dataclass
class ProxyStats:
    to_vehicle: DirectionCounters = field(default_factory=DirectionCounters)
    to_client: DirectionCounters = field(default_factory=DirectionCounters)

    def line(self) -> str:
        """One line a person reads: per direction, forwarded and dropped (lost / cut / no client)."""
        parts = []
        for name in DIRECTIONS:
            c = getattr(self, name)
            parts.append(f"{name.replace('_', ' ')}: {c.received} in, {c.forwarded} forwarded, {c.dropped} dropped "
                         f"({c.lost} lost, {c.cut} cut" + (f", {c.no_client} before a client" if c.no_client else "")
                         + (f", {c.unsent} unsent" if c.unsent else "") + ")")
        return "; ".join(parts)


def parse_host_port(text: str, default_host: str | None = None) -> tuple[str, int]:
    """'HOST:PORT' (or 'PORT' when a default host is given) -> (host, port); ValueError naming the text."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host = default_host or ""
    if not host:
        raise ValueError(f"{text!r}: give HOST:PORT, e.g. 127.0.0.1:14580")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"{text!r}: the port {port!r} is not a number") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"{text!r}: the port {number} is not in 0..65535")
    return host, number


class UdpProxy:
    """Forwards datagrams between one client and one vehicle with loss, delay and cuts.

    listen: (host, port) the client sends to; port 0 picks a free one (see listen_address).
    vehicle: (host, port) of the vehicle.
    loss: fraction 0..1 of the packets dropped in each direction; delay: one-way seconds added.
    cut_at, cut_for: a scheduled cut, seconds after start(), lasting cut_for seconds.
    observe: called as observe(direction, time.monotonic() at arrival, data) for every packet that enters
    the link, in the proxy's thread (keep it short); a bench uses it to time what a vehicle receives.
    """

    def __init__(self, listen: tuple[str, int], vehicle: tuple[str, int], loss: float = 0.0, delay: float = 0.0,
                 cut_at: float | None = None, cut_for: float | None = None, seed: int = 0,
                 observe: Callable[[str, float, bytes], None] | None = None):
        if not 0.0 <= loss <= 1.0:
            raise ValueError(f"loss {loss}: give a fraction from 0 to 1 (0.2 drops one packet in five)")
        if not (delay >= 0.0 and math.isfinite(delay)):
            raise ValueError(f"delay {delay}: give the one-way delay in seconds, >= 0 (0.05 for 50 ms)")
        if (cut_at is None) != (cut_for is None):
            raise ValueError("a scheduled cut needs both cut_at and cut_for (seconds after the start, seconds long)")
        if cut_at is not None and cut_for is not None and not (cut_at >= 0 and cut_for >= 0):  # 0 s cuts nothing
            raise ValueError(f"cut_at {cut_at}, cut_for {cut_for}: give cut_at >= 0 and cut_for >= 0 seconds")
        self.loss, self.delay = float(loss), float(delay)
        self.cut_at, self.cut_for = cut_at, cut_for
        self.seed = seed
        self.observe = observe
        self._random = {name: random.Random(seed * len(DIRECTIONS) + k) for k, name in enumerate(DIRECTIONS)}
        self._lock = threading.RLock()  # re-entrant: a signal handler (cut on SIGUSR1) may interrupt stats()
        self._stats = ProxyStats()
        self._queue: deque[tuple[float, str, bytes, tuple]] = deque()  # (due, direction, data, destination)
        self._client: tuple | None = None
        self._manual_cut_until: float | None = None  # monotonic time; math.inf: until resume()
        self._scheduled_cut: tuple[float, float] | None = None
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._vehicle = self._resolve(vehicle)
        self._listen = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._upstream = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._wake_r, self._wake_w = socket.socketpair()
        try:
            self._listen.bind(listen)
        except OSError as error:
            self._close_sockets()
            raise OSError(f"cannot listen on {listen[0]}:{listen[1]} ({error.strerror or error}); "
                          "another program (a client, a ground station) may hold that port: choose another") from None
        self._upstream.bind(("0.0.0.0", 0))
        for sock in (self._listen, self._upstream, self._wake_r):
            sock.setblocking(False)

    @staticmethod
    def _resolve(address: tuple[str, int]) -> tuple[str, int]:
        try:
            return socket.gethostbyname(address[0]), int(address[1])
        except OSError:
            raise OSError(f"cannot resolve the vehicle's host {address[0]!r}: give an IP address or a known name"
                          ) from None

    # --- what callers see -----------------------------------------------------------------------------

    @property
    def listen_address(self) -> tuple[str, int]:
        return self._listen.getsockname()

    @property
    def vehicle_side_address(self) -> tuple[str, int]:
        """The address the vehicle sees the proxy (and so the client) at."""
        return self._upstream.getsockname()

    @property
    def client(self) -> tuple | None:
        with self._lock:
            return self._client

    def stats(self) -> ProxyStats:
        """A copy of the counters."""
        with self._lock:
            return ProxyStats(DirectionCounters(**vars(self._stats.to_vehicle)),
                              DirectionCounters(**vars(self._stats.to_client)))

    def cut(self, seconds: float | None = None) -> None:
        """Cut the link now: for `seconds`, or until resume()."""
        with self._lock:
            self._manual_cut_until = math.inf if seconds is None else time.monotonic() + seconds

    def resume(self) -> None:
        """End a cut made by cut() (a scheduled cut runs its course)."""
        with self._lock:
            self._manual_cut_until = None

    def is_cut(self, now: float | None = None) -> bool:
        now = time.monotonic() if now is None else now
        with self._lock:
            return self._cut_locked(now)

    def start(self) -> UdpProxy:
        if self._thread is not None:
            raise RuntimeError("the proxy is already started")
        if self.cut_at is not None and self.cut_for is not None:  # __init__ takes both or neither
            begin = time.monotonic() + self.cut_at
            self._scheduled_cut = (begin, begin + self.cut_for)
        self._thread = threading.Thread(target=self._serve, name="udp_proxy", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """End the thread and close every socket; packets still delayed are not sent. Idempotent."""
        self._stopping = True
        if self._thread is not None:
            try:
                self._wake_w.send(b"x")
            except OSError:
                pass
            self._thread.join()
        self._close_sockets()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def __enter__(self) -> UdpProxy:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # --- the loop -----------------------------------------------------------------------------------------

    def _cut_locked(self, now: float) -> bool:
        if self._manual_cut_until is not None:
            if now < self._manual_cut_until:
                return True
            self._manual_cut_until = None
        return self._scheduled_cut is not None and self._scheduled_cut[0] <= now < self._scheduled_cut[1]

    def _serve(self) -> None:
        selector = selectors.DefaultSelector()
        selector.register(self._listen, selectors.EVENT_READ, TO_VEHICLE)
        selector.register(self._upstream, selectors.EVENT_READ, TO_CLIENT)
        selector.register(self._wake_r, selectors.EVENT_READ, None)
        try:
            while not self._stopping:
                timeout = None
                if self._queue:
                    timeout = max(0.0, self._queue[0][0] - time.monotonic())
                for key, _ in selector.select(timeout):
                    if key.data is None:
                        continue  # woken up by stop()
                    sock = key.fileobj
                    assert isinstance(sock, socket.socket)  # only sockets are registered
                    self._drain(sock, key.data)
                self._send_due(time.monotonic())
        finally:
            selector.close()

    def _drain(self, sock: socket.socket, direction: str) -> None:
        while True:
            try:
                data, sender = sock.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. an ICMP error for an earlier send: not a reason to stop
                return
            now = time.monotonic()
            if self.observe is not None:
                self.observe(direction, now, data)
            with self._lock:
                counters = getattr(self._stats, direction)
                counters.received += 1
                if direction == TO_VEHICLE:
                    self._client = sender  # learned from the first packet, follows a client that moved
                    destination = self._vehicle
                elif self._client is None:
                    counters.no_client += 1
                    continue
                else:
                    destination = self._client
                if self._cut_locked(now):
                    counters.cut += 1
                    continue
                # Draw for every packet that is not cut, so a run with the same seed and packets repeats.
                if self._random[direction].random() < self.loss:
                    counters.lost += 1
                    continue
            self._queue.append((now + self.delay, direction, data, destination))

    def _send_due(self, now: float) -> None:
        while self._queue and self._queue[0][0] <= now:
            _, direction, data, destination = self._queue.popleft()
            sock = self._upstream if direction == TO_VEHICLE else self._listen
            with self._lock:  # counted first, so a receiver never sees a packet the counters do not show
                getattr(self._stats, direction).forwarded += 1
            try:
                sock.sendto(data, destination)
            except OSError:  # nobody listening there (yet): a real link loses it too
                with self._lock:
                    counters = getattr(self._stats, direction)
                    counters.forwarded -= 1
                    counters.unsent += 1

    def _close_sockets(self) -> None:
        for sock in (self._listen, self._upstream, self._wake_r, self._wake_w):
            sock.close()


# --- the command line (rosrun magna_mavlink udp_proxy) ------------------------------------------------------

EXAMPLES = """\
examples:
  rosrun magna_mavlink udp_proxy --listen 14590 --to 127.0.0.1:14580 --loss 0.2 --delay 0.05   # [synopsis]
  rosrun magna_mavlink udp_proxy --listen 14590 --to 127.0.0.1:14580 --cut-at 30 --cut-for 5   # [synopsis]
  rosrun magna_mavlink udp_proxy --listen 0 --to 127.0.0.1:14580 --loss 0.2 --duration 1   # a free port, 1 s

A client then connects to the proxy instead of the vehicle, e.g.
  rosrun magna_mavlink ual_mavlink --id 1 --url udpout:127.0.0.1:14590
Signals: SIGUSR1 cuts the link (for --cut-for seconds if given, else until SIGUSR2), SIGUSR2 resumes it;
Ctrl-C or SIGTERM stops the proxy and prints its counters.
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="udp_proxy", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES,
        description="A UDP proxy between a MAVLink vehicle and its client that drops, delays and cuts packets "
                    "in both directions, to test how a mission copes with a bad link.")
    parser.add_argument("--listen", required=True, metavar="[HOST:]PORT",
                        help="where the client sends (host default 0.0.0.0); the client's address is learned from "
                             "its first packet")
    parser.add_argument("--to", required=True, metavar="HOST:PORT",
                        help="the vehicle (PX4 SITL instance i listens on 14580+i)")
    parser.add_argument("--loss", type=float, default=0.0, metavar="FRACTION",
                        help="fraction of packets dropped in each direction, 0..1 (default 0)")
    parser.add_argument("--delay", type=float, default=0.0, metavar="SECONDS",
                        help="one-way delay added to every packet, in order (default 0)")
    parser.add_argument("--cut-at", type=float, metavar="SECONDS", help="cut the link this long after the start")
    parser.add_argument("--cut-for", type=float, metavar="SECONDS", help="how long a cut lasts")
    parser.add_argument("--seed", type=int, default=0, help="seed of the loss draws (default 0)")
    parser.add_argument("--duration", type=float, metavar="SECONDS", help="stop after this long (default: run "
                        "until Ctrl-C or SIGTERM)")
    parser.add_argument("--report-every", type=float, default=0.0, metavar="SECONDS",
                        help="print the counters this often (default: only at the end)")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        listen = parse_host_port(args.listen, default_host="0.0.0.0")
        vehicle = parse_host_port(args.to)
    except ValueError as error:
        parser.error(str(error))
    if args.cut_at is not None and args.cut_for is None:
        parser.error("--cut-at needs --cut-for SECONDS (how long the cut lasts)")
    if args.cut_for is not None and not args.cut_for >= 0:
        parser.error(f"--cut-for {args.cut_for:g}: give the cut's length in seconds, 0 or more")
    try:
        proxy = UdpProxy(listen, vehicle, loss=args.loss, delay=args.delay, cut_at=args.cut_at,
                         cut_for=args.cut_for if args.cut_at is not None else None, seed=args.seed)
    except ValueError as error:
        parser.error(str(error))
    except OSError as error:
        print(f"udp_proxy: {error}", file=sys.stderr)
        return 2
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGUSR1, lambda *_: proxy.cut(args.cut_for))
    signal.signal(signal.SIGUSR2, lambda *_: proxy.resume())
    proxy.start()
    host, port = proxy.listen_address
    print(f"udp_proxy: {host}:{port} <-> {vehicle[0]}:{vehicle[1]}, loss {args.loss:g}, delay {args.delay:g} s"
          + (f", cut at {args.cut_at:g} s for {args.cut_for:g} s" if args.cut_at is not None else "")
          + f", seed {args.seed}", flush=True)
    started = time.monotonic()
    next_report = started + args.report_every if args.report_every > 0 else math.inf
    end = started + args.duration if args.duration is not None else math.inf
    try:
        while not stop.is_set():
            now = time.monotonic()
            if now >= end:
                break
            if now >= next_report:
                print(f"udp_proxy: {proxy.stats().line()}", flush=True)
                next_report += args.report_every
            stop.wait(min(end, next_report, now + 1.0) - now)
    finally:
        proxy.stop()
    print(f"udp_proxy: stopped; {proxy.stats().line()}", flush=True)
    return 0
