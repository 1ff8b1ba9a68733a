"""Action servers speaking the actionlib wire protocol.

`GoalTable` is the protocol itself: the list of goals a server knows with their
states, the `goal`/`cancel` subscriptions, the `status`/`result`/`feedback`
publications and the status heartbeat. `SimpleActionServer` puts the one-goal-at-a-
time policy of actionlib's simple server on top of it, with the same constructor
and methods, so code written for `actionlib.SimpleActionServer` runs unchanged.
"""
from __future__ import annotations

import threading
import traceback
import weakref

import rospy
from actionlib_msgs.msg import GoalID, GoalStatus, GoalStatusArray

from .goal_id import GoalIdGenerator
from .spec import action_topic, action_types
from .status import ACTIVE_STATES, SERVER_TRANSITIONS, is_terminal, status_name

__all__ = ["GoalTable", "ServerGoal", "SimpleActionServer"]

DEFAULT_STATUS_FREQUENCY = 5.0      # Hz, as actionlib
DEFAULT_STATUS_LIST_TIMEOUT = 5.0   # s a finished goal stays in the status list
_ZERO_TIME = rospy.Time()
_EVENT_WORDS = {"accept": "be accepted", "reject": "be rejected", "cancel_request": "be asked to cancel",
                "canceled": "be canceled (preempted/recalled)", "succeed": "succeed", "abort": "be aborted"}


def _on_ros_shutdown(obj, method_name: str) -> None:
    """Call `obj.<method_name>()` when rospy shuts down, without keeping `obj` alive."""
    ref = weakref.ref(obj)

    def hook():
        target = ref()
        if target is not None:
            getattr(target, method_name)()

    rospy.on_shutdown(hook)


def _joined_at_ros_shutdown(thread: threading.Thread) -> None:
    """Have rospy join `thread` at shutdown, once `rospy.is_shutdown()` is True (as it does
    for its own timer threads): user loops that poll `is_shutdown()` end, and the node's
    shutdown waits for them."""
    add = getattr(rospy.core, "_add_shutdown_thread", None)
    if add is not None:
        add(thread)


class ServerGoal:
    """One entry of a server's status list.

    `status` is the `GoalStatus` message published for it; `action_goal` the
    `*ActionGoal` received (None for the placeholder a cancel leaves for a goal
    not received yet); `finished_at` the ROS time it reached a terminal state.
    """

    __slots__ = ("status", "action_goal", "finished_at")

    def __init__(self, status: GoalStatus, action_goal=None):
        self.status = status
        self.action_goal = action_goal
        self.finished_at: rospy.Time | None = None

    @property
    def id(self) -> str:
        return self.status.goal_id.id

    @property
    def stamp(self) -> rospy.Time:
        return self.status.goal_id.stamp

    @property
    def goal(self):
        """The user's `*Goal` message."""
        return None if self.action_goal is None else self.action_goal.goal

    def __repr__(self) -> str:
        return f"<ServerGoal {self.id} {status_name(self.status.status)}>"


class GoalTable:
    """The server half of the actionlib protocol, for any number of goals.

    `goal_cb(goal)` is called for every new goal and `cancel_cb(goal)` for every
    goal a cancel request moved to RECALLING or PREEMPTING; both run under
    `self.lock` (an RLock), from rospy's subscriber threads. The transition
    methods (`accept`, `reject`, `set_canceled`, `set_succeeded`, `set_aborted`)
    enforce the protocol's state machine: an illegal move is logged and refused,
    never raised.
    """

    def __init__(self, ns: str, action_spec, goal_cb, cancel_cb=None, *,
                 status_frequency: float | None = None, status_list_timeout: float | None = None):
        self.ns = ns
        self.types = action_types(action_spec)
        self.lock = threading.RLock()
        self._goal_cb = goal_cb
        self._cancel_cb = cancel_cb
        self._goals: dict[str, ServerGoal] = {}   # insertion order = status list order
        self._last_cancel = rospy.Time()
        self._ids = GoalIdGenerator(ns)  # not the node's name: a process may host many servers
        self._status_frequency = status_frequency
        self._status_list_timeout = status_list_timeout
        self._started = False
        self._stop = threading.Event()
        self._heartbeat: threading.Thread | None = None
        self._pubs: dict[str, rospy.Publisher] = {}
        self._subs: list[rospy.Subscriber] = []

    # Names actionlib's ActionServer exposes, which some user code reads.
    @property
    def ActionSpec(self):  # noqa: N802
        return self.types.spec

    @property
    def ActionGoal(self):  # noqa: N802
        return self.types.action_goal

    @property
    def ActionResult(self):  # noqa: N802
        return self.types.action_result

    @property
    def ActionResultType(self):  # noqa: N802
        return self.types.result

    @property
    def ActionFeedback(self):  # noqa: N802
        return self.types.action_feedback

    # -- life cycle ---------------------------------------------------------------------------------
    def start(self) -> None:
        with self.lock:
            if self._started:
                return
            status_frequency = self._read_parameters()
            queue = rospy.get_param("actionlib_server_pub_queue_size", 50)
            queue = queue if queue > 0 else 50
            self._pubs = {
                "status": rospy.Publisher(action_topic(self.ns, "status"), GoalStatusArray, latch=True,
                                          queue_size=queue),
                # Latched: a client's result subscription may still be completing its handshake when a goal
                # is refused at once; rospy drops a message for such a connection, and actionlib's clients
                # (C++ and Python) then wait for ever. The latched copy reaches it once connected; clients
                # ignore a result whose goal id is not theirs.
                "result": rospy.Publisher(action_topic(self.ns, "result"), self.types.action_result, latch=True,
                                          queue_size=queue),
                "feedback": rospy.Publisher(action_topic(self.ns, "feedback"), self.types.action_feedback,
                                            queue_size=queue),
            }
            self._subs = [
                rospy.Subscriber(action_topic(self.ns, "goal"), self.types.action_goal, self._on_goal_msg,
                                 tcp_nodelay=True),
                rospy.Subscriber(action_topic(self.ns, "cancel"), GoalID, self._on_cancel_msg, tcp_nodelay=True),
            ]
            self._started = True
            self._stop.clear()
            if status_frequency > 0:
                self._heartbeat = threading.Thread(target=self._heartbeat_loop, args=(1.0 / status_frequency,),
                                                   daemon=True, name=f"action status {self.ns}")
                self._heartbeat.start()
                _joined_at_ros_shutdown(self._heartbeat)
            _on_ros_shutdown(self, "_halt_heartbeat")
            self.publish_status()

    def stop(self) -> None:
        """Stop serving: end the heartbeat and unregister every topic. Goals in flight get no result."""
        with self.lock:
            if not self._started:
                return
            self._started = False
            self._stop.set()
            heartbeat, self._heartbeat = self._heartbeat, None
            for handle in [*self._subs, *self._pubs.values()]:
                handle.unregister()
            self._subs, self._pubs = [], {}
        if heartbeat is not None and heartbeat is not threading.current_thread():
            heartbeat.join(timeout=2.0)

    @property
    def started(self) -> bool:
        return self._started

    def _halt_heartbeat(self) -> None:
        self._stop.set()

    def _read_parameters(self) -> float:
        """Fill in the status frequency and list timeout not given to the constructor; return the frequency."""
        if self._status_frequency is None:
            own = action_topic(self.ns, "status_frequency")
            if rospy.has_param(own):
                self._status_frequency = float(rospy.get_param(own))
            else:
                found = rospy.search_param("actionlib_status_frequency")
                self._status_frequency = float(rospy.get_param(found)) if found else DEFAULT_STATUS_FREQUENCY
        if self._status_list_timeout is None:
            self._status_list_timeout = float(rospy.get_param(action_topic(self.ns, "status_list_timeout"),
                                                              DEFAULT_STATUS_LIST_TIMEOUT))
        return self._status_frequency

    def _heartbeat_loop(self, period: float) -> None:
        while not self._stop.wait(period):
            if rospy.is_shutdown():
                return
            self.publish_status()

    # -- publishing ---------------------------------------------------------------------------------
    def _publish(self, topic: str, msg) -> None:
        publisher = self._pubs.get(topic)
        if publisher is None or rospy.is_shutdown():
            return
        try:
            publisher.publish(msg)
        except rospy.ROSException as error:   # closed during shutdown
            rospy.logdebug("%s: not publishing %s: %s", self.ns, topic, error)

    def publish_status(self) -> None:
        """Publish the status list, first dropping finished goals older than the keep time."""
        with self.lock:
            if not self._started:
                return
            now = rospy.Time.now()
            keep = rospy.Duration.from_sec(self._status_list_timeout)
            expired = [key for key, goal in self._goals.items()
                       if goal.finished_at is not None and goal.finished_at + keep < now]
            for key in expired:
                del self._goals[key]
            msg = GoalStatusArray(status_list=[goal.status for goal in self._goals.values()])
            msg.header.stamp = now
            self._publish("status", msg)

    def publish_feedback(self, goal: ServerGoal, feedback) -> None:
        with self.lock:
            msg = self.types.action_feedback()
            msg.header.stamp = rospy.Time.now()
            msg.status = goal.status
            msg.feedback = feedback
            self._publish("feedback", msg)

    def _publish_result(self, goal: ServerGoal, result) -> None:
        msg = self.types.action_result()
        msg.header.stamp = rospy.Time.now()
        msg.status = goal.status
        msg.result = self.types.result() if result is None else result
        self._publish("result", msg)
        self.publish_status()

    # -- state machine ------------------------------------------------------------------------------
    def goals(self) -> list[ServerGoal]:
        with self.lock:
            return list(self._goals.values())

    def _move(self, goal: ServerGoal, event: str, result=None, text: str | None = None, quiet=False) -> bool:
        with self.lock:
            target = SERVER_TRANSITIONS.get((goal.status.status, event))
            if target is None:
                if not quiet:
                    rospy.logerr("%s: goal %s cannot %s: it is %s", self.ns, goal.id, _EVENT_WORDS[event],
                                 status_name(goal.status.status))
                return False
            goal.status.status = target
            if text is not None:
                goal.status.text = text
            if is_terminal(target):
                goal.finished_at = rospy.Time.now()
                self._publish_result(goal, result)
            else:
                self.publish_status()
            return True

    def accept(self, goal: ServerGoal, text: str = "") -> bool:
        """PENDING -> ACTIVE, or RECALLING -> PREEMPTING."""
        return self._move(goal, "accept", text=text)

    def reject(self, goal: ServerGoal, result=None, text: str = "") -> bool:
        """PENDING/RECALLING -> REJECTED."""
        return self._move(goal, "reject", result, text)

    def set_canceled(self, goal: ServerGoal, result=None, text: str = "") -> bool:
        """PENDING/RECALLING -> RECALLED, ACTIVE/PREEMPTING -> PREEMPTED."""
        return self._move(goal, "canceled", result, text)

    def set_succeeded(self, goal: ServerGoal, result=None, text: str = "") -> bool:
        return self._move(goal, "succeed", result, text)

    def set_aborted(self, goal: ServerGoal, result=None, text: str = "") -> bool:
        return self._move(goal, "abort", result, text)

    # -- incoming messages --------------------------------------------------------------------------
    def _call(self, callback, goal: ServerGoal) -> None:
        if callback is None:
            return
        try:
            callback(goal)
        except Exception:   # a user's bug must not take the protocol down with it
            rospy.logerr("%s: callback %r failed:\n%s", self.ns, callback, traceback.format_exc())

    def _on_goal_msg(self, action_goal) -> None:
        with self.lock:
            if not self._started:
                return
            goal_id = action_goal.goal_id
            known = self._goals.get(goal_id.id) if goal_id.id else None
            if known is not None:
                if known.action_goal is None and known.status.status == GoalStatus.RECALLING:
                    # A cancel for this id came first: the goal ends now, never run.
                    known.action_goal = action_goal
                    known.status.goal_id = GoalID(id=goal_id.id, stamp=goal_id.stamp)
                    self._move(known, "canceled", text="Canceled by a request that arrived before the goal")
                # Otherwise a duplicate: never run a goal twice.
                return
            status = GoalStatus(goal_id=GoalID(id=goal_id.id, stamp=goal_id.stamp), status=GoalStatus.PENDING)
            if not status.goal_id.id:
                status.goal_id = self._ids.generate(goal_id.stamp if goal_id.stamp != _ZERO_TIME else None)
            elif status.goal_id.stamp == _ZERO_TIME:
                status.goal_id.stamp = rospy.Time.now()
            goal = ServerGoal(status, action_goal)
            self._goals[goal.id] = goal
            if goal_id.stamp != _ZERO_TIME and goal_id.stamp <= self._last_cancel:
                self._move(goal, "canceled", text="This goal was canceled: its stamp is at or before that of an "
                                                  "earlier cancel request")
                return
            self._call(self._goal_cb, goal)

    def _on_cancel_msg(self, cancel: GoalID) -> None:
        with self.lock:
            if not self._started:
                return
            everything = cancel.id == "" and cancel.stamp == _ZERO_TIME
            by_time = cancel.stamp != _ZERO_TIME
            found = False
            for goal in list(self._goals.values()):
                same_id = cancel.id != "" and cancel.id == goal.id
                found = found or same_id
                if not (everything or same_id or (by_time and goal.stamp <= cancel.stamp)):
                    continue
                if goal.action_goal is not None and self._move(goal, "cancel_request", quiet=True):
                    self._call(self._cancel_cb, goal)
            if cancel.id and not found:
                # Remember the request: the goal may still be on its way (it is then recalled on arrival).
                placeholder = ServerGoal(GoalStatus(goal_id=GoalID(id=cancel.id, stamp=cancel.stamp),
                                                    status=GoalStatus.RECALLING))
                placeholder.finished_at = rospy.Time.now()
                self._goals[cancel.id] = placeholder
            if cancel.stamp > self._last_cancel:
                self._last_cancel = cancel.stamp


_REPLACED = "Canceled: a newer goal reached the simple action server"


class SimpleActionServer:
    """actionlib's `SimpleActionServer`, same constructor and methods, on our protocol code.

    At most one goal is worked on at a time. A new goal preempts the current one
    (the current goal is told through `is_preempt_requested()` and the preempt
    callback); a goal waiting to be accepted that is overtaken by a newer one is
    recalled. With `execute_cb`, goals run one after another in a thread of the
    server's own, and a goal the callback leaves without a terminal state is
    aborted, with a warning.
    """

    def __init__(self, name, ActionSpec, execute_cb=None, auto_start=True,  # noqa: N803 (actionlib's names)
                 *, status_frequency: float | None = None, status_list_timeout: float | None = None):
        self.execute_callback = execute_cb
        self.goal_callback = None
        self.preempt_callback = None
        self.action_server = GoalTable(name, ActionSpec, self._on_goal, self._on_cancel,
                                       status_frequency=status_frequency,
                                       status_list_timeout=status_list_timeout)
        self._lock = self.action_server.lock
        self._wakeup = threading.Condition(self._lock)
        self._current: ServerGoal | None = None
        self._next: ServerGoal | None = None
        self._new_goal = False
        self._preempt_request = False
        self._next_preempt_request = False
        self._terminate = False
        self._thread: threading.Thread | None = None
        if execute_cb is not None:
            self._thread = threading.Thread(target=self._execute_loop, daemon=True,
                                            name=f"SimpleActionServer {name}")
            self._thread.start()
            _joined_at_ros_shutdown(self._thread)
        _on_ros_shutdown(self, "_on_shutdown")
        if auto_start:
            self.start()

    # -- actionlib's API ----------------------------------------------------------------------------
    def start(self) -> None:
        self.action_server.start()

    def accept_new_goal(self):
        """Make the waiting goal the current one (ACTIVE) and return its `*Goal` message.

        A current goal still active is preempted. Returns None (and logs) when no
        new goal is waiting.
        """
        with self._lock:
            if not self._new_goal or self._next is None:
                rospy.logerr("%s: accept_new_goal() called with no new goal available", self.action_server.ns)
                return None
            if self.is_active() and self._current is not self._next:
                self.action_server.set_canceled(self._current, None, _REPLACED)
            self._current, self._next = self._next, None
            self._new_goal = False
            self._preempt_request, self._next_preempt_request = self._next_preempt_request, False
            self.action_server.accept(self._current, "Accepted by the simple action server")
            return self._current.goal

    def is_new_goal_available(self) -> bool:
        return self._new_goal

    def is_preempt_requested(self) -> bool:
        return self._preempt_request

    def is_active(self) -> bool:
        current = self._current
        return current is not None and current.status.status in ACTIVE_STATES

    def set_succeeded(self, result=None, text: str = "") -> None:
        self._finish_current("succeed", result, text)

    def set_aborted(self, result=None, text: str = "") -> None:
        self._finish_current("abort", result, text)

    def set_preempted(self, result=None, text: str = "") -> None:
        self._finish_current("canceled", result, text)

    def publish_feedback(self, feedback) -> None:
        with self._lock:
            if self._current is None:
                rospy.logerr("%s: publish_feedback() with no current goal", self.action_server.ns)
                return
            self.action_server.publish_feedback(self._current, feedback)

    def get_default_result(self):
        return self.action_server.types.result()

    def register_goal_callback(self, cb) -> None:
        if self.execute_callback is not None:
            rospy.logwarn("%s: register_goal_callback() ignored: this server has an execute callback",
                          self.action_server.ns)
            return
        self.goal_callback = cb

    def register_preempt_callback(self, cb) -> None:
        self.preempt_callback = cb

    # -- extensions ---------------------------------------------------------------------------------
    def reject_new_goal(self, result=None, text: str = "") -> bool:
        """Refuse the goal waiting to be accepted (it ends REJECTED). For goal-callback servers
        that validate goals; actionlib's simple server has no way to reject."""
        with self._lock:
            if not self._new_goal or self._next is None:
                rospy.logerr("%s: reject_new_goal() called with no new goal available", self.action_server.ns)
                return False
            goal, self._next = self._next, None
            self._new_goal = False
            self._next_preempt_request = False
            return self.action_server.reject(goal, result, text)

    def current_goal_status(self) -> GoalStatus | None:
        """The status message of the current goal, or None before the first one."""
        current = self._current
        return None if current is None else current.status

    def shutdown(self, timeout: float = 2.0) -> None:
        """Stop the execute thread (after the running callback returns) and stop serving."""
        with self._lock:
            self._terminate = True
            self._wakeup.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
        self.action_server.stop()

    # -- internals ----------------------------------------------------------------------------------
    def _finish_current(self, event: str, result, text: str) -> None:
        with self._lock:
            if self._current is None:
                rospy.logerr("%s: no current goal to finish", self.action_server.ns)
                return
            if result is None:
                result = self.get_default_result()
            self.action_server._move(self._current, event, result, text)

    def _user_callback(self, callback) -> None:
        if callback is None:
            return
        try:
            callback()
        except Exception:
            rospy.logerr("%s: callback %r failed:\n%s", self.action_server.ns, callback, traceback.format_exc())

    def _on_goal(self, goal: ServerGoal) -> None:
        # Runs under the table's lock, in a subscriber thread.
        newest = ((self._current is None or goal.stamp >= self._current.stamp)
                  and (self._next is None or goal.stamp >= self._next.stamp))
        if not newest:
            self.action_server.set_canceled(goal, None, _REPLACED)
            return
        if self._next is not None:
            self.action_server.set_canceled(self._next, None, _REPLACED)
        self._next = goal
        self._new_goal = True
        self._next_preempt_request = False
        if self.is_active():
            self._preempt_request = True
            self._user_callback(self.preempt_callback)
        self._user_callback(self.goal_callback)
        self._wakeup.notify_all()

    def _on_cancel(self, goal: ServerGoal) -> None:
        if goal is self._current:
            self._preempt_request = True
            self._user_callback(self.preempt_callback)
        elif goal is self._next:
            self._next_preempt_request = True

    def _stopping(self) -> bool:
        return self._terminate or rospy.is_shutdown()

    def _execute_loop(self) -> None:
        while True:
            with self._wakeup:
                while not self._new_goal and not self._stopping():
                    self._wakeup.wait(0.5)   # woken by goals and shutdown; the timeout is a safety net
                if self._stopping():
                    return
                goal = self.accept_new_goal()
            if goal is None:
                continue
            try:
                self.execute_callback(goal)
            except Exception as error:
                if self._stopping():
                    return
                rospy.logerr("%s: exception in the execute callback: %s\n%s", self.action_server.ns, error,
                             traceback.format_exc())
                with self._lock:
                    if self.is_active():
                        self.set_aborted(None, f"Exception in execute callback: {error}")
                continue
            with self._lock:
                if self._stopping():
                    if self.is_active():   # the callback gave up because the node is going down
                        self.set_aborted(None, "The action server is shutting down")
                    return
                if self.is_active():
                    rospy.logwarn("%s: the execute callback returned without setting a terminal state "
                                  "(set_succeeded/set_aborted/set_preempted); the goal is aborted",
                                  self.action_server.ns)
                    self.set_aborted(None, "The execute callback returned without setting a terminal state")

    def _on_shutdown(self) -> None:
        # A client shutdown hook: rospy is not shut down yet, so only ask the thread to end
        # (an idle thread ends now; one in the execute callback once it returns).
        with self._lock:
            self._terminate = True
            self._wakeup.notify_all()
        self.action_server._halt_heartbeat()
