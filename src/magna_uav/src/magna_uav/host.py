"""Several UAV managers in one process, nodelet style: the bookkeeping of a manager host, without ROS.

Each manager runs in a thread of its own and keeps its own names, actions, services and beat
(magna_uav.ros_node.UavManagerNode); a die request ends that manager only. The host tells who has
ended (`ended`, published latched on the host's `~ended` by magna_uav.host_node) and is done when
every manager has ended. Each manager reads the private parameters the ground station sets for the
standalone node it replaces (`/uav_{id}_manager/...`) through `private_params`.
"""
from __future__ import annotations

import threading
from collections.abc import Callable, Iterable

ENDED_TOPIC = "ended"  # under the host's node name: /uav_manager_host/ended (std_msgs/UInt32MultiArray, latched)


def manager_node_name(uav_id: int) -> str:
    """The node name a standalone manager of this UAV has (the ground station's __name:=), without the slash."""
    return f"uav_{int(uav_id)}_manager"


def ended_topic(host_name: str) -> str:
    """The latched topic on which the host named `host_name` lists its ended managers."""
    return f"/{host_name.strip('/')}/{ENDED_TOPIC}"


HOST_NODE = "uav_manager_host"  # the node name of a ground station's (first) manager host


def host_groups(ids: Iterable[int], per_host: int) -> list[tuple[str, list[int]]]:
    """The manager hosts that run the managers of `ids`, at most `per_host` each and as even as can be, in id
    order: (node name, ids).

    One host is named uav_manager_host; more are uav_manager_host_1, _2, ... Each host is a process of its
    own, so the managers of a big swarm share the cores instead of one Python interpreter's lock.
    per_host 0 puts them all in one host."""
    ids = sorted(int(i) for i in ids)
    if per_host < 0:
        raise ValueError(f"managers_per_host is {per_host}: give a positive number of managers per host "
                         f"(0: all in one host)")
    if not ids:
        return []
    count = -(-len(ids) // (per_host or len(ids)))  # as few hosts as `per_host` allows, evened out
    base, extra = divmod(len(ids), count)
    bounds = [k * base + min(k, extra) for k in range(count + 1)]
    chunks = [ids[bounds[k]:bounds[k + 1]] for k in range(count)]
    if len(chunks) == 1:
        return [(HOST_NODE, chunks[0])]
    return [(f"{HOST_NODE}_{k}", chunk) for k, chunk in enumerate(chunks, start=1)]


def private_params(node_name: str, get_param: Callable[..., object]) -> Callable[[str, object], object]:
    """A `param(name, default)` for magna_uav.settings.read_settings that reads `~x` as the node `node_name` would:
    `/node_name/x`, through `get_param(full_name, default)` (rospy.get_param, or a dict's get in tests)."""
    namespace = "/" + node_name.strip("/")

    def param(name: str, default: object = None) -> object:
        if not name.startswith("~"):
            raise ValueError(f"{name!r} is not a private parameter (~name); read it with get_param itself")
        return get_param(f"{namespace}/{name[1:]}", default)

    return param


def host_ids(raw: object) -> list[int]:
    """The host's ~ids, checked: a non-empty list of distinct whole numbers; ValueError names the fix."""
    if isinstance(raw, str):  # _ids:=[1,2] from a command line arrives as a list; "1,2" or "1 2" as text
        raw = [part for part in raw.replace(",", " ").split() if part]
    if not isinstance(raw, list | tuple) or not raw:
        raise ValueError(f"~ids is {raw!r}: give the UAV ids whose managers this host runs, e.g. _ids:=[1,2]")
    try:
        ids = [int(i) for i in raw]
    except (TypeError, ValueError):
        raise ValueError(f"~ids is {raw!r}: every id must be a whole number, e.g. _ids:=[1,2]") from None
    if any(isinstance(i, float) and not float(i).is_integer() for i in raw):
        raise ValueError(f"~ids is {raw!r}: every id must be a whole number, e.g. _ids:=[1,2]")
    if len(set(ids)) != len(ids):
        raise ValueError(f"~ids is {raw!r}: an id appears twice; give each UAV once")
    return ids


class ManagerHost:
    """Runs `run_manager(uav_id)` for each id in a thread of its own and keeps who has ended.

    A manager ends when `run_manager` returns or raises (`log_error` says what it raised). After each end,
    `on_ended(ended)` gets every ended id so far, ascending, in the order the ends happened (one at a time).
    `wait()` returns once all have ended.
    """

    def __init__(self, ids: Iterable[int], run_manager: Callable[[int], object],
                 on_ended: Callable[[list[int]], None] = lambda ended: None,
                 log_error: Callable[[str], None] = lambda message: None):
        self.ids = list(ids)
        if not self.ids or len(set(self.ids)) != len(self.ids):
            raise ValueError(f"a manager host needs distinct UAV ids, got {self.ids}")
        self._run_manager = run_manager
        self._on_ended = on_ended
        self._log_error = log_error
        self._lock = threading.Lock()
        self._ended: list[int] = []
        self._all_ended = threading.Event()
        self.threads = {uav_id: threading.Thread(target=self._run, args=(uav_id,), daemon=True,
                                                 name=manager_node_name(uav_id)) for uav_id in self.ids}

    def start(self) -> ManagerHost:
        for thread in self.threads.values():
            thread.start()
        return self

    @property
    def ended(self) -> list[int]:
        with self._lock:
            return sorted(self._ended)

    def running(self, uav_id: int) -> bool:
        with self._lock:
            return uav_id in self.threads and uav_id not in self._ended

    def wait(self, timeout: float | None = None) -> bool:
        """True once every manager has ended (within `timeout` s when given)."""
        return self._all_ended.wait(timeout)

    def _run(self, uav_id: int) -> None:
        try:
            self._run_manager(uav_id)
        except BaseException as error:  # noqa: BLE001 -- one manager's failure must not end the others
            self._log_error(f"UAV {uav_id} manager ended by an error: {error!r}")
        finally:
            with self._lock:
                self._ended.append(uav_id)
                ended = sorted(self._ended)
                try:
                    self._on_ended(ended)
                except Exception as error:  # noqa: BLE001 -- the bookkeeping goes on
                    self._log_error(f"telling that UAV {uav_id}'s manager ended failed: {error!r}")
                if len(ended) == len(self.ids):
                    self._all_ended.set()


def describe_hosted(uav_id: int, host_cause: str | None, ended: Iterable[int]) -> str | None:
    """Why a hosted manager cannot beat, for the ground station's liveness probe: its host process's state
    (`host_cause`, magna_common.liveness.describe_process; None while it runs), else its own thread's end, as
    the host's ended list says; None while both run."""
    if host_cause is not None:
        return f"its manager host {host_cause}"
    if uav_id in set(ended):
        return "thread ended (its manager host runs on)"
    return None
