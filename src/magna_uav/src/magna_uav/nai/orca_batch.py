"""ORCA-3D for the UAV managers of one process: one solver call per control step for all of them.

A manager host runs each UAV's manager in a thread of its own, all stepping at the same
simulated tick. Each manager's `OrcaNavigator` builds its own problem as it always has (its
own neighbour selection and parameters) and hands it to the shared `OrcaBatcher`:

    batcher = OrcaBatcher()                     # one per process
    with batcher.joined(uav_id):                # each manager thread, around its whole life
        ... batcher.solve(uav_id, tick, problem) -> Solution   # blocks, see below

`solve` waits until every joined participant has submitted for that step key, then ONE
`new_velocity_many` call serves them all and each gets its own answer. Each problem is solved
as if alone (magna_orca_cpp's many service, or its reference problem by problem), so the
answers are the same bit for bit as one call per UAV whatever the grouping: the waiting
decides only how many calls are made, never what they answer.

Nobody waits for ever on a participant that stops stepping: a round closes when no new
submission has arrived for STRAGGLER_WAIT (wall clock); whoever was missing is then marked
idle and not waited for again until it submits. `leave` (in a finally) removes a participant
at once. The solver and its fallback order are the single path's (`default_solver`: the
service, else the numpy reference). A refused or failing many-call is redone problem by
problem, so only the UAV whose problem was bad gets the error, as on the single path.

`solve_alone` answers a problem outside any round (a step off the shared tick, such as a role's
first) at once. The solver is used by one thread at a time: its service connection is persistent,
and a rospy connection must not carry two calls at once.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Hashable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

from magna_orca_cpp.model import Problem, Solution
from magna_uav.nai.orca import default_solver

logger = logging.getLogger("magna_uav.nai")

# Longest wall-clock gap between two submissions of one step before the round is solved
# without the missing participants. The managers of a host wake on the same /clock tick and
# each computes its step in Python (GIL) before submitting, so submissions arrive well under a
# millisecond apart; 4 ms leaves room for a loaded machine, and costs a silent participant's
# peers 4 ms once (it is then idle, so not waited for, until it submits again).
STRAGGLER_WAIT = 0.004


@dataclass(eq=False)
class _Round:
    """The submissions of one step key, until one thread takes them to the solver."""

    problems: dict[int, Problem] = field(default_factory=dict)
    last_arrival: float = 0.0  # time.monotonic() of the latest submission
    closed: bool = False  # taken to the solver: no more submissions
    done: bool = False  # answers are in
    answers: dict[int, Solution | Exception] = field(default_factory=dict)


class OrcaBatcher:
    """One many-call per step for the participants of one process (see the module docstring)."""

    def __init__(self, solver=None, straggler_wait: float = STRAGGLER_WAIT):
        if not straggler_wait > 0:
            raise ValueError(f"OrcaBatcher straggler_wait is {straggler_wait!r}: give a positive number of seconds")
        self._solver = solver
        self.straggler_wait = float(straggler_wait)
        self._cond = threading.Condition()
        self._solver_busy = threading.Lock()  # one call on the solver at a time (rounds of two keys may overlap)
        self._members: set[int] = set()
        self._idle: set[int] = set()  # joined, but missed a step: not waited for until they submit
        self._last_key: dict[int, Hashable] = {}  # each member's latest submitted step key
        self._rounds: dict[Hashable, _Round] = {}  # open rounds by step key
        self.rounds = 0  # rounds solved: one many-call each (unless redone problem by problem)

    @property
    def solver(self):
        """The single path's solver (service, else reference), made on first use."""
        with self._cond:
            if self._solver is None:
                self._solver = default_solver()
            return self._solver

    @property
    def participants(self) -> frozenset[int]:
        with self._cond:
            return frozenset(self._members)

    def join(self, uav_id: int) -> None:
        with self._cond:
            if uav_id in self._members:
                raise ValueError(f"UAV {uav_id} has already joined this ORCA-3D batcher: join once per manager")
            self._members.add(uav_id)

    def leave(self, uav_id: int) -> None:
        """No longer waited for; safe to call for a participant that has already left."""
        with self._cond:
            self._members.discard(uav_id)
            self._idle.discard(uav_id)
            self._last_key.pop(uav_id, None)
            self._cond.notify_all()  # a round may have been waiting only for this one

    @contextmanager
    def joined(self, uav_id: int) -> Iterator[OrcaBatcher]:
        """join, and leave however the block ends."""
        self.join(uav_id)
        try:
            yield self
        finally:
            self.leave(uav_id)

    def _missing(self, key: Hashable, submitted: dict[int, Problem]) -> set[int]:
        """Members still expected for `key`: joined, not idle, not yet submitted it."""
        return {m for m in self._members - self._idle if m not in submitted and self._last_key.get(m) != key}

    def solve(self, uav_id: int, step_key: Hashable, problem: Problem) -> Solution:
        """This UAV's answer to `problem`, solved in one call with the other participants' of `step_key`.

        `step_key` names the control step and must be equal for every participant at the same
        tick (e.g. the tick index); it only groups problems. Raises what the single path would
        raise for this problem (OrcaInputError for bad input)."""
        with self._cond:
            if uav_id not in self._members:
                raise ValueError(f"UAV {uav_id} has not joined this ORCA-3D batcher: call join({uav_id}) (or use "
                                 f"`with batcher.joined({uav_id}):`) before solve")
            current = self._rounds.get(step_key)
            if current is None:
                current = self._rounds[step_key] = _Round()
            if uav_id in current.problems:
                raise ValueError(f"UAV {uav_id} submitted twice for step {step_key!r}: one problem per UAV and step")
            current.problems[uav_id] = problem
            current.last_arrival = time.monotonic()
            self._idle.discard(uav_id)
            self._last_key[uav_id] = step_key
            # Waiters are woken only when their round is answered (or someone leaves); the last to
            # submit finds nobody missing and takes the round itself.
            while not current.closed:
                missing = self._missing(step_key, current.problems)
                if not missing:
                    break
                remaining = current.last_arrival + self.straggler_wait - time.monotonic()
                if remaining <= 0:
                    self._idle |= missing
                    logger.debug("ORCA-3D step %r solved without UAV(s) %s (silent for %.1f ms)", step_key,
                                 sorted(missing), 1e3 * self.straggler_wait)
                    break
                self._cond.wait(remaining)
            if current.closed:  # another thread took the round: wait for its answers
                while not current.done:
                    self._cond.wait()
                return self._answer(current, uav_id)
            current.closed = True
            del self._rounds[step_key]
        answers: dict[int, Solution | Exception] = {}
        try:
            answers = self._solve_round(current.problems)
        finally:  # answers or not, nobody may be left waiting
            with self._cond:
                current.answers, current.done = answers, True
                self._cond.notify_all()
        return self._answer(current, uav_id)

    def solve_alone(self, problem: Problem) -> Solution:
        """`problem` answered by itself, at once, with no round and no join (the single path's call)."""
        solver = self.solver
        with self._solver_busy:
            return solver.new_velocity(problem.agent, problem.neighbors, problem.params)

    @staticmethod
    def _answer(finished: _Round, uav_id: int) -> Solution:
        answer = finished.answers.get(uav_id)
        if answer is None:
            raise RuntimeError(f"ORCA-3D batch gave no answer for UAV {uav_id}: the round's solve failed")
        if isinstance(answer, Exception):
            raise answer
        return answer

    def _solve_round(self, problems: dict[int, Problem]) -> dict[int, Solution | Exception]:
        with self._solver_busy:
            return self._solve_round_now(problems)

    def _solve_round_now(self, problems: dict[int, Problem]) -> dict[int, Solution | Exception]:
        solver = self.solver
        ids = list(problems)
        ordered = [problems[i] for i in ids]
        self.rounds += 1
        many = getattr(solver, "new_velocity_many", None)
        if many is not None:
            try:
                solutions: Sequence[Solution] = many(ordered)
                if len(solutions) != len(ordered):
                    raise RuntimeError(f"new_velocity_many gave {len(solutions)} answers for {len(ordered)} problems")
                return dict(zip(ids, solutions, strict=True))
            except Exception as err:  # one bad problem refuses the call: redo alone, so only its UAV gets the error
                logger.debug("ORCA-3D many-call of %d problems failed (%s): solving them one by one", len(ids), err)
        answers: dict[int, Solution | Exception] = {}
        for uav_id, p in zip(ids, ordered, strict=True):
            try:
                answers[uav_id] = solver.new_velocity(p.agent, p.neighbors, p.params)
            except Exception as err:
                answers[uav_id] = err
        return answers


__all__ = ["STRAGGLER_WAIT", "OrcaBatcher"]
