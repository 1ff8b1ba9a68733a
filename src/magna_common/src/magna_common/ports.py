"""Free network ports, picked by the OS, for nodes and tests that must not collide with others."""
from __future__ import annotations

import socket


def free_port(host: str = "127.0.0.1", udp: bool = False) -> int:
    """A TCP (or UDP) port that nothing is bound to right now."""
    kind = socket.SOCK_DGRAM if udp else socket.SOCK_STREAM
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


def free_udp_ports(count: int, host: str = "127.0.0.1") -> list[int]:
    """`count` distinct UDP ports, all free when asked (held together so the OS cannot repeat one)."""
    sockets = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
    try:
        for sock in sockets:
            sock.bind((host, 0))
        return [sock.getsockname()[1] for sock in sockets]
    finally:
        for sock in sockets:
            sock.close()
