"""The manager host's bookkeeping and parameters, without ROS: fake managers that end when told."""
import threading

import pytest

from magna_uav.host import (
    ManagerHost,
    describe_hosted,
    ended_topic,
    host_groups,
    host_ids,
    manager_node_name,
    private_params,
)
from magna_uav.settings import SettingsError, read_settings
from tests.support import wait_until


class FakeManagers:
    """Managers that run until their die event is set; one may raise instead of ending."""

    def __init__(self, failing: int | None = None):
        self.die = {}
        self.started = set()
        self.failing = failing
        self.lock = threading.Lock()

    def run(self, uav_id: int) -> None:
        event = threading.Event()
        with self.lock:
            self.die[uav_id] = event
            self.started.add(uav_id)
        event.wait(30.0)
        if uav_id == self.failing:
            raise RuntimeError("the UAL services never came")


def test_each_manager_ends_alone_and_the_host_is_done_when_all_have_ended():
    managers, told, errors = FakeManagers(failing=3), [], []
    host = ManagerHost([1, 2, 3], managers.run, on_ended=told.append, log_error=errors.append).start()
    wait_until(lambda: managers.started == {1, 2, 3}, "three managers running")
    assert {name: t.name for name, t in host.threads.items()} == {1: "uav_1_manager", 2: "uav_2_manager",
                                                                    3: "uav_3_manager"}
    managers.die[2].set()
    wait_until(lambda: host.ended == [2], "UAV 2's manager to end")
    assert host.running(1) and not host.running(2) and host.running(3) and not host.running(9)
    assert not host.wait(0.05)  # the others run on
    managers.die[3].set()  # this one raises: it has ended all the same, and the error is said
    wait_until(lambda: host.ended == [2, 3], "UAV 3's manager to end")
    assert errors == ["UAV 3 manager ended by an error: RuntimeError('the UAL services never came')"]
    assert host.threads[1].is_alive() and not host.wait(0.05)
    managers.die[1].set()
    assert host.wait(10.0)
    assert told == [[2], [2, 3], [1, 2, 3]]  # every end told, with all the ended ones so far
    assert not any(t.is_alive() for t in host.threads.values())


def test_a_failing_listener_does_not_stop_the_bookkeeping():
    managers, errors = FakeManagers(), []

    def listener(ended):
        raise OSError("publisher gone")

    host = ManagerHost([5], managers.run, on_ended=listener, log_error=errors.append).start()
    wait_until(lambda: managers.started == {5}, "the manager running")
    managers.die[5].set()
    assert host.wait(10.0) and host.ended == [5]
    assert errors == ["telling that UAV 5's manager ended failed: OSError('publisher gone')"]


def test_a_host_needs_distinct_ids():
    with pytest.raises(ValueError, match=r"distinct UAV ids, got \[1, 1\]"):
        ManagerHost([1, 1], lambda uav_id: None)
    with pytest.raises(ValueError, match="distinct UAV ids"):
        ManagerHost([], lambda uav_id: None)


@pytest.mark.parametrize(("raw", "ids"), [([1, 2], [1, 2]), ((3,), [3]), ("1, 4", [1, 4]), ([2.0], [2])])
def test_host_ids_are_read_from_a_list_or_text(raw, ids):
    assert host_ids(raw) == ids


@pytest.mark.parametrize(("raw", "message"), [
    (None, "~ids is None: give the UAV ids"), ([], "~ids is \\[\\]: give the UAV ids"),
    (["a"], "every id must be a whole number"), ([1.5], "every id must be a whole number"),
    ([1, 1], "an id appears twice")])
def test_bad_host_ids_are_refused_with_the_fix(raw, message):
    with pytest.raises(ValueError, match=message):
        host_ids(raw)


def test_each_manager_reads_the_private_parameters_of_the_node_it_replaces(tmp_path):
    server = {  # what the ground station sets for two standalone managers, as a ROS parameter server holds it
        "/uav_1_manager/id": 1, "/uav_1_manager/uav_ids": [1, 2], "/uav_1_manager/control_rate": 20.0,
        "/uav_1_manager/data_dir": str(tmp_path), "/uav_1_manager/csv_stream": str(tmp_path / "uav_1.csv"),
        "/uav_2_manager/id": "2", "/uav_2_manager/uav_ids": [1, 2], "/uav_2_manager/low_battery": 0.3,
        "/ids": [7],  # a global parameter of the same name is not a manager's
    }
    asked = []

    def get_param(name, default=None):
        asked.append(name)
        return server.get(name, default)

    one = read_settings(private_params(manager_node_name(1), get_param))
    two = read_settings(private_params("/uav_2_manager/", get_param))
    assert (one.uav_id, one.control_rate, one.data_dir, one.csv_stream) == (1, 20.0, tmp_path, tmp_path / "uav_1.csv")
    assert (two.uav_id, two.control_rate, two.low_battery, two.csv_stream) == (2, 10.0, 0.3, None)
    assert [c.id for c in two.configs] == [1, 2]
    assert all(name.startswith(("/uav_1_manager/", "/uav_2_manager/")) for name in asked)
    with pytest.raises(SettingsError, match="~id is missing"):
        read_settings(private_params(manager_node_name(3), get_param))
    with pytest.raises(ValueError, match="'/ids' is not a private parameter"):
        private_params("uav_1_manager", get_param)("/ids", None)


def test_the_ended_topic_is_under_the_hosts_name():
    assert ended_topic("uav_manager_host") == ended_topic("/uav_manager_host/") == "/uav_manager_host/ended"


def test_a_hosted_manager_is_described_by_its_host_then_by_its_thread():
    assert describe_hosted(2, None, []) is None  # both run
    assert describe_hosted(2, None, [1]) is None  # another one ended
    assert describe_hosted(2, None, [1, 2]) == "thread ended (its manager host runs on)"
    # the host gone: every one of its managers, ended or not, says so
    assert describe_hosted(2, "killed by SIGKILL", [2]) == "its manager host killed by SIGKILL"
    assert describe_hosted(1, "stopped (frozen: SIGSTOP or a debugger)", []) == (
        "its manager host stopped (frozen: SIGSTOP or a debugger)")


def test_managers_are_shared_out_evenly_among_as_few_hosts_as_the_limit_allows():
    assert host_groups([2, 1], 10) == [("uav_manager_host", [1, 2])]
    assert host_groups(range(1, 11), 0) == [("uav_manager_host", list(range(1, 11)))]  # 0: one host
    assert host_groups(range(1, 13), 10) == [("uav_manager_host_1", [1, 2, 3, 4, 5, 6]),
                                            ("uav_manager_host_2", [7, 8, 9, 10, 11, 12])]
    groups = host_groups(range(1, 51), 12)
    assert [len(g) for _, g in groups] == [10, 10, 10, 10, 10]
    assert sorted(i for _, g in groups for i in g) == list(range(1, 51))
    assert [name for name, _ in groups] == [f"uav_manager_host_{k}" for k in range(1, 6)]
    assert host_groups([], 10) == []
    with pytest.raises(ValueError, match="managers_per_host is -1"):
        host_groups([1], -1)
