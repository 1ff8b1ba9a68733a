"""Free ports really are free: they can be bound at once."""
import socket

from magna_common.ports import free_port, free_udp_ports


def test_a_free_tcp_port_can_be_listened_on():
    port = free_port()
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.listen()


def test_free_udp_ports_are_distinct_and_bindable():
    ports = free_udp_ports(3)
    assert len(set(ports)) == 3
    sockets = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in ports]
    try:
        for sock, port in zip(sockets, ports, strict=True):
            sock.bind(("127.0.0.1", port))
    finally:
        for sock in sockets:
            sock.close()
    assert free_port(udp=True) > 0
