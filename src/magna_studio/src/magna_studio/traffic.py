"""What flows between the bridge and one page, without ROS: who may connect, the throttle of a
subscription, the bounded outbox, per-page counts, and the thread pool of blocking service calls."""
from __future__ import annotations

import concurrent.futures
import queue
import re
import threading
from collections import OrderedDict, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

CALL_WORKERS = 4
MAX_QUEUED_TOPIC_MESSAGES = 256  # per page
MAX_QUEUED_REPLIES = 256  # per page: service responses and statuses, never dropped


# --- who may connect -------------------------------------------------------------------------------------

_ORIGIN = re.compile(r"(https?)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+)(?::([0-9]{1,5}|\*))?/?")


class OriginPolicy:
    """The page origins allowed to connect: `scheme://host[:port]`, the port `*` for any (or none)."""

    def __init__(self, patterns: Sequence[str]):
        self.patterns = [self.parse(pattern) for pattern in patterns]

    @staticmethod
    def parse(pattern: str) -> tuple[str, str, str | None]:
        """(scheme, host, port) of an origin or a pattern; ValueError when it is neither."""
        match = _ORIGIN.fullmatch(pattern.strip())
        if match is None:
            raise ValueError(f"{pattern!r} is not an origin: give scheme://host[:port], the port * for any, "
                             "e.g. http://localhost:*")
        scheme, host, port = match.groups()
        return scheme.lower(), host.lower(), port

    def allows(self, origin: str | None) -> bool:
        if origin is None:  # not a browser: the cross-site attack needs one
            return True
        try:
            scheme, host, port = self.parse(origin)
        except ValueError:  # "null" (a file: page, a sandbox) and anything odd
            return False
        if port == "*":
            return False
        return any(scheme == p_scheme and host == p_host and p_port in ("*", port)
                   for p_scheme, p_host, p_port in self.patterns)


# --- per page: throttle and outbox (pure) --------------------------------------------------------------------

class Throttle:
    """rosbridge's throttle_rate and queue_length for one page and topic: a message at most every `interval`
    seconds; those arriving meanwhile wait, the newest `hold` of them, and go out one per interval."""

    def __init__(self, interval: float, hold: int):
        self.interval = interval
        self.hold = hold
        self._held: deque[str] = deque()
        self._next = -float("inf")
        self.dropped = 0

    def offer(self, item: str, now: float) -> str | None:
        """The item to send now, or None when it waits (or is dropped: `hold` 0, or newer ones pushed it out)."""
        if self.interval <= 0:
            return item
        if not self._held and now >= self._next:
            self._next = now + self.interval
            return item
        self._held.append(item)
        if len(self._held) > self.hold:
            self._held.popleft()
            self.dropped += 1
        return None

    def release(self, now: float) -> str | None:
        """The oldest waiting item once its time has come."""
        if not self._held or now < self._next:
            return None
        self._next = now + self.interval
        return self._held.popleft()

    @property
    def wake_at(self) -> float | None:
        """When a waiting item may go, or None when none waits."""
        return self._next if self._held else None


class OutboxFull(RuntimeError):
    pass


class Outbox:
    """What waits to be written to one page, oldest first. Topic messages are bounded: beyond the bound the
    oldest message of the topic with most waiting is dropped (a fast topic cannot push out a slow one's last
    message). Replies are never dropped: beyond their bound put_reply raises OutboxFull."""

    def __init__(self, max_topic_messages: int = MAX_QUEUED_TOPIC_MESSAGES, max_replies: int = MAX_QUEUED_REPLIES):
        self.max_topic_messages = max_topic_messages
        self.max_replies = max_replies
        self._items: OrderedDict[int, tuple[str | None, str]] = OrderedDict()  # sequence -> (topic or None, text)
        self._by_topic: dict[str, deque[int]] = {}
        self._topic_count = 0
        self._reply_count = 0
        self._sequence = 0
        self.dropped = 0

    def put_topic(self, topic: str, text: str) -> None:
        if self._topic_count >= self.max_topic_messages:
            crowded = max(self._by_topic, key=lambda name: len(self._by_topic[name]))
            self._forget(crowded)
            self.dropped += 1
        self._sequence += 1
        self._items[self._sequence] = (topic, text)
        self._by_topic.setdefault(topic, deque()).append(self._sequence)
        self._topic_count += 1

    def put_reply(self, text: str) -> None:
        if self._reply_count >= self.max_replies:
            raise OutboxFull(f"{self._reply_count} replies wait unread")
        self._sequence += 1
        self._items[self._sequence] = (None, text)
        self._reply_count += 1

    def pop(self) -> str | None:
        if not self._items:
            return None
        _, (topic, text) = self._items.popitem(last=False)
        if topic is None:
            self._reply_count -= 1
        else:
            self._forget(topic, remove_item=False)
        return text

    def _forget(self, topic: str, remove_item: bool = True) -> None:
        sequences = self._by_topic[topic]
        oldest = sequences.popleft()
        if not sequences:
            del self._by_topic[topic]
        if remove_item:
            del self._items[oldest]
        self._topic_count -= 1

    def __len__(self) -> int:
        return len(self._items)


@dataclass
class ClientStats:
    peer: str
    sent: int = 0  # frames written to the page
    dropped: int = 0  # topic messages dropped because the page read too slowly
    throttled: int = 0  # topic messages skipped by the page's throttle_rate/queue_length
    refused: int = 0  # frames refused by the protocol or the limiter
    calls: int = 0  # service calls made


# --- service calls ---------------------------------------------------------------------------------------

class ServiceCallFailed(RuntimeError):
    pass


class CallPool:
    """A few daemon threads for blocking service calls: a call stuck on a dead service never holds up the node's
    exit (a ThreadPoolExecutor's threads are joined at exit). A job cancelled before it starts never runs."""

    def __init__(self, workers: int = CALL_WORKERS):
        self._jobs: queue.SimpleQueue[tuple[concurrent.futures.Future, Callable[..., Any], tuple] | None] = \
            queue.SimpleQueue()
        self._threads = [threading.Thread(target=self._work, name=f"bridge call {n}", daemon=True)
                         for n in range(workers)]
        for thread in self._threads:
            thread.start()

    def submit(self, function: Callable[..., Any], *args: Any) -> concurrent.futures.Future:
        future: concurrent.futures.Future = concurrent.futures.Future()
        self._jobs.put((future, function, args))
        return future

    def _work(self) -> None:
        while (job := self._jobs.get()) is not None:
            future, function, args = job
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(function(*args))
            except BaseException as error:  # handed to the waiting coroutine, which reports it
                future.set_exception(error)

    def shutdown(self) -> None:
        for _ in self._threads:
            self._jobs.put(None)
