"""The bridge's pure parts: who may connect, the throttle per page and topic, and the bounded outbox."""
import threading

import pytest

from magna_studio.bridge import DEFAULT_ORIGINS, url_of
from magna_studio.traffic import CallPool, OriginPolicy, Outbox, OutboxFull, Throttle

GUARD = 30.0  # s: a guard against hangs, not a speed expectation


def test_default_origins_are_the_local_pages_on_any_port():
    policy = OriginPolicy(DEFAULT_ORIGINS)
    for origin in ("http://127.0.0.1:8000", "http://localhost:5173", "http://LOCALHOST:1", "http://localhost",
                   "http://[::1]:8080", None):
        assert policy.allows(origin), origin
    for origin in ("http://evil.example", "http://127.0.0.1.evil.example:8000", "http://localhost.evil:80",
                   "https://localhost:8000", "http://127.0.0.2:8000", "null", "", "file://", "http://localhost:*",
                   "http://user@localhost:8000", "http://localhost:8000/../x", "http://[::2]:80",
                   "http://localhost:8000\nX: y"):
        assert not policy.allows(origin), origin


def test_given_origins_replace_the_defaults():
    policy = OriginPolicy(["http://127.0.0.1:8000", "https://studio.lab.example:*"])
    assert policy.allows("http://127.0.0.1:8000") and policy.allows("https://studio.lab.example:443")
    assert not policy.allows("http://127.0.0.1:8001") and not policy.allows("http://localhost:8000")
    assert not policy.allows("http://studio.lab.example:80")


@pytest.mark.parametrize("pattern", ["localhost:8000", "ftp://localhost", "http://", "http://a b", "*",
                                     "http://localhost:99999999"])
def test_a_bad_origin_pattern_is_refused_with_an_example(pattern):
    with pytest.raises(ValueError, match="give scheme://host"):
        OriginPolicy([pattern])


def test_url_of_brackets_ipv6():
    assert url_of("127.0.0.1", 9090) == "ws://127.0.0.1:9090/" and url_of("::1", 80) == "ws://[::1]:80/"


def test_throttle_sends_the_first_then_one_per_interval_the_newest_waiting():
    throttle = Throttle(interval=1.0, hold=1)
    assert throttle.offer("a", now=10.0) == "a"
    assert throttle.offer("b", now=10.2) is None and throttle.wake_at == 11.0
    assert throttle.offer("c", now=10.5) is None  # pushes b out
    assert throttle.release(now=10.9) is None
    assert throttle.release(now=11.0) == "c" and throttle.wake_at is None
    assert throttle.offer("d", now=11.5) is None and throttle.wake_at == 12.0  # 1 s after c went
    assert throttle.release(now=12.0) == "d"
    assert throttle.offer("e", now=20.0) == "e"  # quiet for long enough: at once
    assert throttle.dropped == 1


def test_throttle_holds_queue_length_messages_and_releases_them_one_per_interval():
    throttle = Throttle(interval=0.5, hold=3)
    assert throttle.offer("m0", 0.0) == "m0"
    for n in range(1, 6):
        assert throttle.offer(f"m{n}", 0.1 * n) is None
    assert throttle.dropped == 2  # m1, m2: the three newest wait
    assert [throttle.release(t) for t in (0.5, 0.6, 1.0, 1.5, 2.0)] == ["m3", None, "m4", "m5", None]


def test_queue_length_zero_drops_what_comes_within_the_interval_and_no_throttle_passes_all():
    throttle = Throttle(interval=1.0, hold=0)
    assert throttle.offer("a", 0.0) == "a" and throttle.offer("b", 0.5) is None and throttle.wake_at is None
    assert throttle.offer("c", 1.0) == "c" and throttle.dropped == 1
    free = Throttle(interval=0.0, hold=1)
    assert [free.offer(str(n), 0.0) for n in range(5)] == ["0", "1", "2", "3", "4"]


def test_outbox_keeps_order_and_drops_the_oldest_of_the_busiest_topic():
    outbox = Outbox(max_topic_messages=4, max_replies=10)
    outbox.put_topic("/magna/sm/mission/status", "status 1")
    for n in range(3):
        outbox.put_topic("/clock", f"clock {n}")
    outbox.put_reply("reply")
    outbox.put_topic("/clock", "clock 3")  # full: /clock's oldest goes, the status stays
    outbox.put_topic("/clock", "clock 4")
    assert outbox.dropped == 2 and len(outbox) == 5
    assert [outbox.pop() for _ in range(6)] == ["status 1", "clock 2", "reply", "clock 3", "clock 4", None]


def test_outbox_never_drops_replies_and_says_when_they_pile_up():
    outbox = Outbox(max_topic_messages=1, max_replies=2)
    outbox.put_reply("r1")
    outbox.put_topic("/clock", "c1")
    outbox.put_topic("/clock", "c2")
    outbox.put_reply("r2")
    with pytest.raises(OutboxFull):
        outbox.put_reply("r3")
    assert [outbox.pop(), outbox.pop(), outbox.pop()] == ["r1", "c2", "r2"]
    outbox.put_reply("r3")  # room again once read
    assert outbox.pop() == "r3" and outbox.pop() is None


def test_a_call_cancelled_while_queued_never_runs():
    pool = CallPool(workers=1)
    release, ran = threading.Event(), []
    try:
        busy = pool.submit(lambda: release.wait(GUARD))
        queued = pool.submit(ran.append, "queued")
        assert queued.cancel()  # the one worker is busy: the call is still waiting
        release.set()
        assert busy.result(GUARD) is True
        assert pool.submit(ran.append, "after").result(GUARD) is None  # one worker, in order: queued came first
        assert ran == ["after"]
        failing = pool.submit(int, "not a number")
        with pytest.raises(ValueError):
            failing.result(GUARD)
    finally:
        release.set()
        pool.shutdown()
