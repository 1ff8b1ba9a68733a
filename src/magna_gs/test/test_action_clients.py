"""magna_gs.factory.ActionClients: clients of different UAVs are made at the same time, one per (UAV, action)."""
import threading

import pytest

from magna_gs.factory import ActionClients


class Client:
    def __init__(self, key):
        self.key, self.stopped = key, False

    def stop(self):
        self.stopped = True


class GatedClients(ActionClients):
    """Making a client waits for `gate`, as waiting for an action server does."""

    def __init__(self, gate_count: int):
        super().__init__()
        self.inside = threading.Barrier(gate_count, timeout=10)  # all makers inside _make at once, or it breaks
        self.made = []

    def _make(self, uav_id, action):
        self.made.append((uav_id, action))
        self.inside.wait()
        return Client((uav_id, action))


def test_clients_of_different_uavs_are_made_at_the_same_time():
    clients = GatedClients(gate_count=3)
    got = {}
    threads = [threading.Thread(target=lambda i=i: got.__setitem__(i, clients.get(i, "save_csv"))) for i in (1, 2, 3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(15)
    assert not clients.inside.broken, "one maker waited for another: they were made one after the other"
    assert {i: c.key for i, c in got.items()} == {i: (i, "save_csv") for i in (1, 2, 3)}


def test_two_threads_asking_for_one_client_get_the_same_and_it_is_made_once():
    clients = GatedClients(gate_count=1)
    got = []
    threads = [threading.Thread(target=lambda: got.append(clients.get(4, "land"))) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(15)
    assert len(got) == 4 and all(c is got[0] for c in got)
    assert clients.made == [(4, "land")]


def test_a_client_made_after_stop_is_stopped_and_refused():
    clients = GatedClients(gate_count=1)
    kept = clients.get(1, "land")
    clients.stop()
    assert kept.stopped
    with pytest.raises(RuntimeError, match="UAV 2: no take_off client: the ground station is finishing"):
        clients.get(2, "take_off")
