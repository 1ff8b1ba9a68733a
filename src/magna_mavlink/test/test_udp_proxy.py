"""The fault-injecting UDP proxy with plain sockets on free ports: forwarding both ways, the client
learned from its first packet, seeded loss (counted, not timed), delay (never an upper bound),
cuts on command and on a schedule, and a stop that leaves no thread or socket behind."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

from magna_common.ports import free_port
from magna_mavlink.udp_proxy import UdpProxy, parse_host_port

WAIT = 10.0  # s: a guard against hangs, never a speed expectation


def wait_until(predicate, what: str, timeout: float = WAIT) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.002)
    raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")


def udp_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(WAIT)
    return sock


def receive(sock: socket.socket, timeout: float = WAIT) -> tuple[bytes, tuple]:
    sock.settimeout(timeout)
    return sock.recvfrom(65535)


def nothing_waiting(sock: socket.socket) -> bool:
    sock.setblocking(False)
    try:
        sock.recvfrom(65535)
    except BlockingIOError:
        return True
    finally:
        sock.settimeout(WAIT)
    return False


@pytest.fixture
def link():
    """(make_proxy, client, vehicle): the sockets and every proxy made are closed afterwards."""
    client, vehicle = udp_socket(), udp_socket()
    made = []

    def make_proxy(**faults) -> UdpProxy:
        proxy = UdpProxy(("127.0.0.1", 0), vehicle.getsockname(), **faults).start()
        made.append(proxy)
        return proxy

    yield make_proxy, client, vehicle
    for proxy in made:
        proxy.stop()
    client.close()
    vehicle.close()


def vehicle_port_of(proxy: UdpProxy) -> int:
    return proxy.vehicle_side_address[1]


def test_forwards_both_ways_and_learns_the_client_from_its_first_packet(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy()
    assert proxy.client is None
    client.sendto(b"heartbeat from the client", proxy.listen_address)
    data, sender = receive(vehicle)
    assert data == b"heartbeat from the client" and sender[1] == vehicle_port_of(proxy)
    assert proxy.client == client.getsockname()
    vehicle.sendto(b"heartbeat from the vehicle", sender)  # the vehicle answers whoever spoke, as PX4 does
    data, sender = receive(client)
    assert data == b"heartbeat from the vehicle" and sender[1] == proxy.listen_address[1]
    stats = proxy.stats()
    assert (stats.to_vehicle.forwarded, stats.to_client.forwarded) == (1, 1)
    assert stats.to_vehicle.dropped == stats.to_client.dropped == 0


def test_vehicle_packets_before_any_client_are_dropped_and_a_moved_client_is_followed(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy()
    vehicle.sendto(b"early", ("127.0.0.1", vehicle_port_of(proxy)))
    wait_until(lambda: proxy.stats().to_client.no_client == 1, "the early vehicle packet to be counted")
    client.sendto(b"hello", proxy.listen_address)
    _, proxy_side = receive(vehicle)
    with udp_socket() as moved:  # the same client restarted on another port
        moved.sendto(b"hello again", proxy.listen_address)
        receive(vehicle)
        vehicle.sendto(b"reply", proxy_side)
        assert receive(moved)[0] == b"reply"
    assert nothing_waiting(client)


def send_counted(proxy: UdpProxy, sender: socket.socket, to: tuple, receiver: socket.socket, count: int,
                 direction: str) -> list[int]:
    """Send packets numbered 0..count-1 in batches, each forwarded or lost and read before the next, so no
    kernel buffer overflows and the proxy draws for every packet; the numbers that arrived, in order."""
    got = []
    sent = 0
    while sent < count:
        batch = min(50, count - sent)
        for k in range(sent, sent + batch):
            sender.sendto(k.to_bytes(4, "big"), to)
        sent += batch

        def settled(n=sent):
            c = getattr(proxy.stats(), direction)
            return c.forwarded + c.lost == n

        wait_until(settled, f"the proxy to forward or drop {sent} packets {direction}")
        forwarded = getattr(proxy.stats(), direction).forwarded
        while len(got) < forwarded:
            got.append(int.from_bytes(receive(receiver)[0][-4:], "big"))
    assert nothing_waiting(receiver)
    return got


def lossy_run(link, seed: int, count: int = 2000) -> tuple[int, list[int]]:
    make_proxy, client, vehicle = link
    proxy = make_proxy(loss=0.2, seed=seed)
    delivered = send_counted(proxy, client, proxy.listen_address, vehicle, count, "to_vehicle")
    lost = proxy.stats().to_vehicle.lost
    proxy.stop()
    return lost, delivered


def test_seeded_loss_drops_the_given_fraction_repeatably_and_in_order(link):
    count = 2000
    lost, delivered = lossy_run(link, seed=7, count=count)
    assert 0.17 <= lost / count <= 0.23, f"{lost} of {count} lost, asked 20 %"
    assert len(delivered) == count - lost
    assert delivered == sorted(delivered), "the proxy reordered packets"
    again_lost, again_delivered = lossy_run(link, seed=7, count=count)
    assert (again_lost, again_delivered) == (lost, delivered), "the same seed gave another run"


def test_loss_applies_to_the_vehicle_to_client_direction_too(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy(loss=0.2, seed=3)
    client.sendto(b"hello", proxy.listen_address)
    _, proxy_side = receive(vehicle)
    count = 1000
    delivered = send_counted(proxy, vehicle, proxy_side, client, count, "to_client")
    stats = proxy.stats().to_client
    assert 0.16 <= stats.lost / count <= 0.24, f"{stats.lost} of {count} lost, asked 20 %"
    assert len(delivered) == count - stats.lost and delivered == sorted(delivered)


def test_every_packet_is_delayed_at_least_the_given_time_in_both_directions(link):
    make_proxy, client, vehicle = link
    delay = 0.05
    proxy = make_proxy(delay=delay)
    for k in range(5):
        sent = time.monotonic()
        client.sendto(b"c%d" % k, proxy.listen_address)
        data, proxy_side = receive(vehicle)
        assert data == b"c%d" % k and time.monotonic() - sent >= delay
        sent = time.monotonic()
        vehicle.sendto(b"v%d" % k, proxy_side)
        data, _ = receive(client)
        assert data == b"v%d" % k and time.monotonic() - sent >= delay


def test_delayed_packets_keep_their_order(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy(delay=0.02)
    for k in range(100):
        client.sendto(k.to_bytes(4, "big"), proxy.listen_address)
    assert [int.from_bytes(receive(vehicle)[0], "big") for _ in range(100)] == list(range(100))
    assert proxy.stats().to_vehicle.forwarded == 100


def test_a_cut_on_command_drops_everything_then_the_link_resumes(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy()
    client.sendto(b"hello", proxy.listen_address)
    _, proxy_side = receive(vehicle)
    proxy.cut()
    assert proxy.is_cut()
    for k in range(20):
        client.sendto(b"lost %d" % k, proxy.listen_address)
        vehicle.sendto(b"lost %d" % k, proxy_side)
    wait_until(lambda: proxy.stats().to_vehicle.cut == 20 and proxy.stats().to_client.cut == 20,
               "40 packets cut")
    assert nothing_waiting(vehicle) and nothing_waiting(client)
    proxy.resume()
    client.sendto(b"back", proxy.listen_address)
    assert receive(vehicle)[0] == b"back"
    vehicle.sendto(b"back too", proxy_side)
    assert receive(client)[0] == b"back too"


def test_a_timed_cut_on_command_ends_by_itself(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy()
    proxy.cut(0.2)
    assert proxy.is_cut()
    wait_until(lambda: not proxy.is_cut(), "the 0.2 s cut to end")
    client.sendto(b"after the cut", proxy.listen_address)
    assert receive(vehicle)[0] == b"after the cut"


def test_a_scheduled_cut_covers_its_window_only(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy(cut_at=100.0, cut_for=5.0)
    start = time.monotonic()
    assert not proxy.is_cut()
    assert proxy.is_cut(start + 100.5) and proxy.is_cut(start + 104.5)
    assert not proxy.is_cut(start + 106.0)
    now_cut = make_proxy(cut_at=0.0, cut_for=60.0)  # cut from its start, for longer than this test
    client.sendto(b"into the cut", now_cut.listen_address)
    wait_until(lambda: now_cut.stats().to_vehicle.cut == 1, "the packet to be cut")
    assert nothing_waiting(vehicle)


def test_an_observer_sees_every_packet_entering_the_link_with_its_arrival_time(link):
    make_proxy, client, vehicle = link
    seen = []
    proxy = make_proxy(loss=1.0, observe=lambda direction, at, data: seen.append((direction, at, data)))
    before = time.monotonic()
    client.sendto(b"observed, then lost", proxy.listen_address)
    wait_until(lambda: proxy.stats().to_vehicle.lost == 1, "the packet to be lost")
    assert [(d, data) for d, _, data in seen] == [("to_vehicle", b"observed, then lost")]
    assert before <= seen[0][1] <= time.monotonic()


def test_stop_ends_the_thread_and_closes_every_socket(link):
    make_proxy, client, vehicle = link
    proxy = make_proxy(delay=0.5)
    client.sendto(b"still delayed at the stop", proxy.listen_address)
    wait_until(lambda: proxy.stats().to_vehicle.received == 1, "the packet to enter the link")
    port = proxy.listen_address[1]
    proxy.stop()
    assert not proxy.running
    assert not [t for t in threading.enumerate() if t.name == "udp_proxy"]
    assert all(sock.fileno() == -1 for sock in (proxy._listen, proxy._upstream, proxy._wake_r, proxy._wake_w))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
        again.bind(("127.0.0.1", port))  # the port is free again
    proxy.stop()  # a second stop is harmless


def test_bad_settings_are_refused_with_the_fix():
    with pytest.raises(ValueError, match="fraction from 0 to 1"):
        UdpProxy(("127.0.0.1", 0), ("127.0.0.1", 9), loss=1.5)
    with pytest.raises(ValueError, match="both cut_at and cut_for"):
        UdpProxy(("127.0.0.1", 0), ("127.0.0.1", 9), cut_at=3.0)
    with pytest.raises(ValueError, match="cut_for >= 0"):
        UdpProxy(("127.0.0.1", 0), ("127.0.0.1", 9), cut_at=3.0, cut_for=-1.0)
    nothing_cut = UdpProxy(("127.0.0.1", 0), ("127.0.0.1", 9), cut_at=0.0, cut_for=0.0).start()
    assert not nothing_cut.is_cut()  # a fleet file may say cut_for: 0
    nothing_cut.stop()
    with pytest.raises(ValueError, match="HOST:PORT"):
        parse_host_port("14580")
    assert parse_host_port("14590", default_host="0.0.0.0") == ("0.0.0.0", 14590)
    with pytest.raises(ValueError, match="not a number"):
        parse_host_port("localhost:mav")


def run_cli(*args: str, **kwargs) -> subprocess.Popen:
    code = "import sys; from magna_mavlink.udp_proxy import main; sys.exit(main())"
    return subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kwargs)


def test_cli_refuses_bad_options_with_status_2():
    for args, words in ((["--listen", "0", "--to", "nowhere"], "HOST:PORT"),
                        (["--listen", "0", "--to", "127.0.0.1:14580", "--cut-at", "3"], "--cut-at needs --cut-for"),
                        (["--listen", "0", "--to", "127.0.0.1:14580", "--loss", "2"], "fraction from 0 to 1")):
        process = run_cli(*args)
        out, err = process.communicate(timeout=60)
        assert process.returncode == 2 and words in err, err


def test_cli_forwards_and_stops_cleanly_on_sigterm():
    with udp_socket() as vehicle, udp_socket() as client:
        port = free_port(udp=True)
        host, vport = vehicle.getsockname()
        process = run_cli("--listen", f"127.0.0.1:{port}", "--to", f"{host}:{vport}", "--delay", "0.01")
        try:
            assert "udp_proxy: 127.0.0.1:" in process.stdout.readline()  # started and bound
            client.sendto(b"through the process", ("127.0.0.1", port))
            assert receive(vehicle)[0] == b"through the process"
            os.kill(process.pid, signal.SIGTERM)
            out, err = process.communicate(timeout=WAIT)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
        assert process.returncode == 0, err
        assert "stopped; to vehicle: 1 in, 1 forwarded, 0 dropped" in out
