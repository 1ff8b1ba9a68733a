"""The UDP link of one simulated MAVLink vehicle, laid out as PX4 SITL's.

The vehicle binds `local_port` (PX4 SITL: 14580 + instance) on all interfaces and answers whoever
sends to it (a ground station with `udpout:127.0.0.1:14580`); it also sends everything to
`remote_host:remote_port` (14540 + instance), where an offboard API listens (MAVSDK
`udpin://0.0.0.0:14540`, pymavlink `udpin:0.0.0.0:14540`), and reads that API's answers on the
same socket. The socket never blocks: the simulation loop calls `receive()` and `send()` between
physics steps, so a silent or slow client cannot hold the simulation up.
"""
from __future__ import annotations

import socket
import time

from pymavlink.dialects.v20 import common as mavlink

from .mavlink_vehicle import COMPONENT_ID

PEER_TIMEOUT = 10.0  # wall s: a client that sent nothing for this long is no longer written to
MAX_DATAGRAM = 65535


class EndpointError(OSError):
    """The link could not be opened; the message names the port and the fix."""


class MavlinkEndpoint:
    def __init__(self, system_id: int, local_port: int, remote_port: int, remote_host: str = "127.0.0.1",
                 bind_host: str = "0.0.0.0", clock=time.monotonic):
        self.system_id = system_id
        self.local_port = local_port
        self.remote = (remote_host, remote_port)
        self._clock = clock
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._socket.bind((bind_host, local_port))
        except OSError as err:
            self._socket.close()
            raise EndpointError(f"mavlink_local_port: UDP {bind_host}:{local_port} cannot be bound ({err.strerror}); "
                                "another vehicle or PX4 SITL uses it: pick a free port") from None
        self._socket.setblocking(False)
        # Packs what the vehicle says: MAVLink 2, as system `system_id`, component 1 (the autopilot).
        self._packer = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=COMPONENT_ID)
        self._parsers: dict[tuple, mavlink.MAVLink] = {}  # one per sender: MAVLink streams are parsed per link
        self._peers: dict[tuple, float] = {}  # sender address -> wall time last heard
        self.sent = 0
        self.received = 0

    @property
    def closed(self) -> bool:
        return self._socket.fileno() < 0

    def receive(self) -> list[mavlink.MAVLink_message]:
        """Every message waiting on the socket (never blocks)."""
        messages: list[mavlink.MAVLink_message] = []
        while True:
            try:
                data, address = self._socket.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return messages
            except ConnectionRefusedError:  # an ICMP error of an earlier send to a port nobody listens on
                continue
            except OSError:  # closed under us (the model was deleted)
                return messages
            self._peers[address] = self._clock()
            parser = self._parsers.get(address)
            if parser is None:
                parser = self._parsers[address] = mavlink.MAVLink(None)
                parser.robust_parsing = True  # bad bytes become BAD_DATA instead of exceptions
            for message in parser.parse_buffer(data) or ():
                if message.get_type() != "BAD_DATA":
                    messages.append(message)
            self.received += 1

    def send(self, messages) -> None:
        """Pack each message once and send it to the offboard port and to every client heard recently."""
        if not messages:
            return
        now = self._clock()
        for address in [a for a, heard in self._peers.items() if now - heard > PEER_TIMEOUT]:
            del self._peers[address]
            self._parsers.pop(address, None)
        destinations = {self.remote, *self._peers}
        for message in messages:
            data = message.pack(self._packer)
            self._packer.seq = (self._packer.seq + 1) % 256
            for address in destinations:
                try:
                    self._socket.sendto(data, address)
                except OSError:  # full buffer or nobody there: telemetry is best effort, as over a radio
                    pass
            self.sent += 1

    def close(self) -> None:
        self._socket.close()
