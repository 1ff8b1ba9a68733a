"""The bridge node: the studio's page and ROS, over a WebSocket, in a checked subset of rosbridge's protocol.

    rosrun magna_studio bridge [--port 9090] [--bind 127.0.0.1] [--allow-origin URL ...]

Each frame the page sends is checked by magna_studio.protocol against the allow list (magna_studio.allowed);
a refused one is answered with rosbridge's status error and the connection stays open. The ROS side:
- one rospy.Subscriber per topic, shared by every page watching it; rospy's threads hand each message, turned
  into JSON once, to the tornado IOLoop (IOLoop.add_callback), which alone touches the connections;
- per page and topic a throttle (throttle_rate, queue_length, as rosbridge's);
- per page a bounded outbox written one frame at a time: a slow page loses its oldest topic messages (of the
  topic with most waiting), never a service response; a page that leaves even those unread is disconnected;
- service calls in a few daemon threads (rospy.ServiceProxy), answered as service_response with result false
  and the error when the call fails or takes longer than --call-timeout; a call still waiting in the pool at
  its timeout is never sent.
Only pages from the allowed origins may connect (cross-site WebSocket hijacking); clients without an Origin
header (not browsers) may. Per-page counts (sent, dropped, throttled, refused, calls) are logged as the page
leaves, for benches.
"""
from __future__ import annotations

import argparse
import asyncio
import json
import signal
import sys
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import rospy
import tornado.web
import tornado.websocket
from tornado.httpserver import HTTPServer
from tornado.ioloop import IOLoop
from tornado.netutil import bind_sockets

from magna_studio.protocol import (
    MAX_FRAME_BYTES,
    CallService,
    ConnectionLimiter,
    ProtocolError,
    RateLimited,
    Request,
    Subscribe,
    Unsubscribe,
    parse_request,
)
from magna_studio.ros_json import dict_to_message, message_class, message_to_dict, service_class
from magna_studio.traffic import (
    CALL_WORKERS,
    CallPool,
    ClientStats,
    OriginPolicy,
    Outbox,
    OutboxFull,
    ServiceCallFailed,
    Throttle,
)

DEFAULT_PORT = 9090  # rosbridge's
DEFAULT_ADDRESS = "127.0.0.1"
DEFAULT_ORIGINS = ("http://127.0.0.1:*", "http://localhost:*", "http://[::1]:*")
CALL_TIMEOUT = 10.0  # s
# tornado closes a connection whose frame is larger; the protocol refuses (with a status) those between.
MAX_INCOMING_FRAME = 4 * MAX_FRAME_BYTES
ROS_QUEUE_SIZE = 10  # per topic, in rospy: what the IOLoop has not taken yet


def _dumps(data: Any) -> str:
    return json.dumps(data, separators=(",", ":"), allow_nan=False)


def call_service(service: str, type_name: str, args: dict[str, Any]) -> dict[str, Any]:
    """One blocking call (in a pool thread): the response as JSON-ready data, or ServiceCallFailed."""
    service_type = service_class(type_name)
    request = dict_to_message(service_type._request_class, args)
    proxy = rospy.ServiceProxy(service, service_type)
    try:
        response = proxy.call(request)
    except (rospy.ServiceException, rospy.ROSException) as error:
        raise ServiceCallFailed(str(error)) from None
    finally:
        proxy.close()
    return message_to_dict(response)


# --- the hub: topics shared by the pages, calls --------------------------------------------------------------

class Bridge:
    """The ROS side and the registry of connected pages. Every method but `_on_ros_message` runs on the IOLoop."""

    def __init__(self, loop: IOLoop, call_timeout: float = CALL_TIMEOUT, workers: int = CALL_WORKERS,
                 log: Callable[[str], None] = print):
        self.loop = loop
        self.call_timeout = call_timeout
        self.log = log
        self.sessions: set[Session] = set()
        self._watchers: dict[str, set[Session]] = {}
        self._subscribers: dict[str, Any] = {}  # topic -> rospy.Subscriber
        self._calls = CallPool(workers)
        self._closed = False

    def watch(self, session: Session, topic: str, type_name: str) -> None:
        if topic not in self._subscribers:
            # rospy's thread calls back; its queue drops the oldest when the IOLoop falls behind.
            self._subscribers[topic] = rospy.Subscriber(topic, message_class(type_name), self._on_ros_message,
                                                        topic, queue_size=ROS_QUEUE_SIZE)
        self._watchers.setdefault(topic, set()).add(session)

    def unwatch(self, session: Session, topic: str) -> None:
        watchers = self._watchers.get(topic)
        if watchers is None:
            return
        watchers.discard(session)
        if not watchers:
            del self._watchers[topic]
            self._subscribers.pop(topic).unregister()

    def _on_ros_message(self, msg: Any, topic: str) -> None:
        """In a rospy thread: the message as JSON once for every page, handed to the IOLoop."""
        if self._closed:
            return
        text = _dumps({"op": "publish", "topic": topic, "msg": message_to_dict(msg)})
        try:
            self.loop.add_callback(self._fan_out, topic, text)
        except RuntimeError:  # the loop closed while rospy was still delivering
            pass

    def _fan_out(self, topic: str, text: str) -> None:
        now = self.loop.time()
        for session in list(self._watchers.get(topic, ())):
            session.deliver(topic, text, now)

    async def call(self, request: CallService) -> dict[str, Any]:
        """The service_response to a checked call."""
        answer: dict[str, Any] = {"op": "service_response", "service": request.service}
        if request.id is not None:
            answer["id"] = request.id
        future = self._calls.submit(call_service, request.service, request.type, request.args)
        try:
            values = await asyncio.wait_for(asyncio.wrap_future(future), self.call_timeout)
            return {**answer, "values": values, "result": True}
        except TimeoutError:
            # A call still queued is dropped: a command must not be carried out long after the page gave up.
            sent = "it was not sent" if future.cancel() else "it may have been carried out"
            error = f"no answer within {self.call_timeout:g} s ({sent})"
        except ServiceCallFailed as failure:
            error = str(failure)
        except Exception as failure:  # a fault of ours: the page still gets its answer
            self.log(f"bridge: calling {request.service} failed: {failure!r}")
            error = f"the bridge could not make the call: {failure}"
        return {**answer, "values": f"{request.service}: {error}", "result": False}

    def add(self, session: Session) -> None:
        self.sessions.add(session)

    def remove(self, session: Session) -> None:
        self.sessions.discard(session)
        self.log(f"bridge: page {session.stats.peer} left: {_dumps(asdict(session.stats))}")

    def stats(self) -> list[ClientStats]:
        return [session.stats for session in self.sessions]

    def close(self) -> None:
        for session in list(self.sessions):
            session.disconnect(1001, "the bridge is stopping")
        self._closed = True
        for subscriber in self._subscribers.values():
            subscriber.unregister()
        self._subscribers.clear()
        self._watchers.clear()
        self._calls.shutdown()


# --- one page ------------------------------------------------------------------------------------------------

@dataclass
class TopicWatch:
    throttle: Throttle
    timer: object | None = None  # the IOLoop timeout that releases held messages


class Session:
    """One connected page: its requests, subscriptions, limits and outbox. Runs on the IOLoop."""

    def __init__(self, bridge: Bridge, send: Callable[[str], Awaitable[None]], close: Callable[[int, str], None],
                 peer: str, limiter: ConnectionLimiter | None = None, outbox: Outbox | None = None):
        self.bridge = bridge
        self.send = send
        self.close = close
        self.limiter = limiter or ConnectionLimiter()
        self.outbox = outbox or Outbox()
        self.watches: dict[str, TopicWatch] = {}
        self._counts = ClientStats(peer)
        self._throttled_before = 0  # by the throttles of topics no longer watched
        self._ready = asyncio.Event()
        self._ended = False
        self._sender = asyncio.ensure_future(self._send_loop())
        self.bridge.add(self)

    @property
    def stats(self) -> ClientStats:
        self._counts.dropped = self.outbox.dropped
        self._counts.throttled = self._throttled_before + sum(w.throttle.dropped for w in self.watches.values())
        return self._counts

    # incoming

    def receive(self, frame: str | bytes) -> None:
        try:
            self.limiter.admit_message()
            self._handle(parse_request(frame))
        except RateLimited as error:
            self._counts.refused += 1
            if error.report:
                self._reply(error.to_status())
        except ProtocolError as error:
            self._counts.refused += 1
            self._reply(error.to_status())

    def _handle(self, request: Request) -> None:
        if isinstance(request, Subscribe):
            self._subscribe(request)
        elif isinstance(request, Unsubscribe):
            if request.topic not in self.watches:
                self._reply(_status("warning", f"unsubscribe: not subscribed to {request.topic}", request.id))
                return
            self._unwatch(request.topic)
        else:
            try:
                self.limiter.start_call()
            except ProtocolError as error:
                raise error.in_request(request.op, request.id) from None
            self._counts.calls += 1
            asyncio.ensure_future(self._call(request))

    def _subscribe(self, request: Subscribe) -> None:
        try:
            self.limiter.admit_subscription(request.topic, self.watches)
        except ProtocolError as error:
            raise error.in_request(request.op, request.id) from None
        old = self.watches.pop(request.topic, None)
        if old is not None:  # a new subscribe sets new rates
            self._cancel_timer(old)
            self._throttled_before += old.throttle.dropped
        self.watches[request.topic] = TopicWatch(Throttle(request.throttle_rate / 1000.0, request.queue_length))
        try:
            self.bridge.watch(self, request.topic, request.type)
        except Exception as failure:  # rospy or a missing message class: the page is told, the bridge goes on
            del self.watches[request.topic]
            self._reply(_status("error", f"subscribe: {request.topic} cannot be watched: {failure}", request.id))

    async def _call(self, request: CallService) -> None:
        try:
            answer = await self.bridge.call(request)
        finally:
            self.limiter.end_call()
        if not self._ended:
            self._reply(answer)

    # outgoing

    def deliver(self, topic: str, text: str, now: float) -> None:
        watch = self.watches.get(topic)
        if watch is None or self._ended:
            return
        ready = watch.throttle.offer(text, now)
        if ready is not None:
            self._queue_topic(topic, ready)
        self._arm(topic, watch)

    def _arm(self, topic: str, watch: TopicWatch) -> None:
        wake_at = watch.throttle.wake_at
        if wake_at is not None and watch.timer is None:
            watch.timer = self.bridge.loop.call_at(wake_at, self._release, topic)

    def _release(self, topic: str) -> None:
        watch = self.watches.get(topic)
        if watch is None or self._ended:
            return
        watch.timer = None
        ready = watch.throttle.release(self.bridge.loop.time())
        if ready is not None:
            self._queue_topic(topic, ready)
        self._arm(topic, watch)

    def _queue_topic(self, topic: str, text: str) -> None:
        self.outbox.put_topic(topic, text)
        self._ready.set()

    def _reply(self, message: dict[str, Any]) -> None:
        try:
            self.outbox.put_reply(_dumps(message))
        except OutboxFull as full:
            self.disconnect(1008, f"the page does not read its answers: {full}")
            return
        self._ready.set()

    async def _send_loop(self) -> None:
        # One frame at a time: a frame is written once the previous one left, so a slow page's backlog stays in
        # the bounded outbox instead of tornado's unbounded stream buffer.
        while not self._ended:
            text = self.outbox.pop()
            if text is None:
                self._ready.clear()
                await self._ready.wait()
                continue
            try:
                await self.send(text)
            except tornado.websocket.WebSocketClosedError:
                return
            self._counts.sent += 1

    # leaving

    def disconnect(self, code: int, reason: str) -> None:
        self.close(code, reason)
        self.end()

    def end(self) -> None:
        if self._ended:
            return
        self._ended = True
        self._ready.set()
        for topic in list(self.watches):
            self._unwatch(topic)
        self.bridge.remove(self)

    def _unwatch(self, topic: str) -> None:
        watch = self.watches.pop(topic)
        self._cancel_timer(watch)
        self._throttled_before += watch.throttle.dropped
        self.bridge.unwatch(self, topic)

    def _cancel_timer(self, watch: TopicWatch) -> None:
        if watch.timer is not None:
            self.bridge.loop.remove_timeout(watch.timer)
            watch.timer = None


def _status(level: str, text: str, request_id: str | None) -> dict[str, Any]:
    status: dict[str, Any] = {"op": "status", "level": level, "msg": text}
    if request_id is not None:
        status["id"] = request_id
    return status


# --- the WebSocket server ------------------------------------------------------------------------------------

class BridgeSocket(tornado.websocket.WebSocketHandler):
    def initialize(self, bridge: Bridge, origins: OriginPolicy) -> None:
        self.bridge = bridge
        self.origins = origins
        self.session: Session | None = None

    def prepare(self) -> None:
        # Checked here for every request: tornado itself waves through a page whose Origin matches the Host
        # header, which is what a DNS-rebinding page sends.
        if not self.origins.allows(self.request.headers.get("Origin")):
            raise tornado.web.HTTPError(403, "origin not allowed")

    def check_origin(self, origin: str) -> bool:
        return self.origins.allows(origin)

    def open(self, *args: str, **kwargs: str) -> None:
        peer = f"{self.request.remote_ip}#{id(self):x}"
        self.session = Session(self.bridge, self.write_message, self.close, peer)

    def on_message(self, message: str | bytes) -> None:
        if self.session is not None:
            self.session.receive(message)

    def on_close(self) -> None:
        if self.session is not None:
            self.session.end()


def make_app(bridge: Bridge, origins: OriginPolicy) -> tornado.web.Application:
    return tornado.web.Application([(r"/", BridgeSocket, {"bridge": bridge, "origins": origins})],
                                   websocket_max_message_size=MAX_INCOMING_FRAME,
                                   websocket_ping_interval=20.0, websocket_ping_timeout=20.0)


def url_of(address: str, port: int) -> str:
    host = f"[{address}]" if ":" in address else address
    return f"ws://{host}:{port}/"


async def serve(address: str, port: int, origins: OriginPolicy, call_timeout: float = CALL_TIMEOUT,
                log: Callable[[str], None] = print) -> None:
    """Listen until SIGINT, SIGTERM or rospy's shutdown; print `bridge: ws://ADDR:PORT/` once listening."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)

    def stop_from_rospy() -> None:
        try:
            loop.call_soon_threadsafe(stop.set)
        except RuntimeError:  # the loop has ended already
            pass

    rospy.on_shutdown(stop_from_rospy)
    bridge = Bridge(IOLoop.current(), call_timeout, log=log)
    sockets = bind_sockets(port, address)
    server = HTTPServer(make_app(bridge, origins))
    server.add_sockets(sockets)
    print(f"bridge: {url_of(address, sockets[0].getsockname()[1])}", flush=True)
    try:
        if not rospy.is_shutdown():
            await stop.wait()
    finally:
        server.stop()
        bridge.close()


# --- the node ----------------------------------------------------------------------------------------------

def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{port} is not a port: give 0 to 65535 (0: any free port)")
    return port


def _origin(text: str) -> str:
    try:
        OriginPolicy.parse(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rosrun magna_studio bridge",
        description="The studio's WebSocket bridge to ROS: a checked subset of rosbridge's protocol (subscribe, "
                    "unsubscribe, call_service) for the topics and services listed in magna_studio.allowed. "
                    "Prints 'bridge: ws://ADDR:PORT/' once listening. Private parameters ~port, ~address and "
                    "~allow_origin (a list) stand in for the options.")
    parser.add_argument("--port", type=_port, default=None,
                        help=f"port to listen on (default: ~port or {DEFAULT_PORT}; 0: any free port)")
    parser.add_argument("--bind", metavar="ADDR", default=None,
                        help=f"address to listen on (default: ~address or {DEFAULT_ADDRESS})")
    parser.add_argument("--allow-origin", metavar="URL", type=_origin, action="append", default=None,
                        help="a page origin allowed to connect, e.g. http://127.0.0.1:8000 or http://localhost:*; "
                             f"repeatable (default: {', '.join(DEFAULT_ORIGINS)}); clients sending no Origin, "
                             "which are not browsers, are always allowed")
    parser.add_argument("--call-timeout", type=float, default=CALL_TIMEOUT, metavar="S",
                        help=f"seconds a service call may take (default {CALL_TIMEOUT:g})")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(rospy.myargv(list(sys.argv if argv is None else argv))[1:])
    rospy.init_node("magna_studio_bridge", disable_signals=True)  # the IOLoop handles SIGINT and SIGTERM
    try:
        port = args.port if args.port is not None else _port(str(rospy.get_param("~port", DEFAULT_PORT)))
        address = args.bind or str(rospy.get_param("~address", DEFAULT_ADDRESS))
        param_origins = rospy.get_param("~allow_origin", [])
        patterns = args.allow_origin or ([param_origins] if isinstance(param_origins, str) else param_origins)
        origins = OriginPolicy(patterns or DEFAULT_ORIGINS)
    except (argparse.ArgumentTypeError, ValueError, TypeError) as error:
        print(f"bridge: {error}", file=sys.stderr)
        return 2
    try:
        asyncio.run(serve(address, port, origins, args.call_timeout, log=rospy.loginfo))
    except OSError as error:
        print(f"bridge: cannot listen on {url_of(address, port)}: {error}", file=sys.stderr)
        return 1
    finally:
        rospy.signal_shutdown("bridge stopped")
    return 0
