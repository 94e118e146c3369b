"""Episodes of several policies in lockstep, for timing them under the same machine load.

On a shared machine the speed of a core drifts by tens of percent within a minute, so two episodes
timed one after the other compare two loads as much as two code paths. :func:`run_in_lockstep` runs
each episode in its own thread and lets them take turns: a turn is ``steps`` policy steps and the
simulation steps and bookkeeping after them, and only the thread whose turn it is runs. Turns of
several steps keep the episodes from evicting each other's working set from the caches at every
step (a cost no real cell pays), turns of seconds still share the load's drift. Each thread's
CPU time (:func:`time.thread_time`, torch on one thread) is then measured over the same stretch of
the machine's load as the others'. Threads only take turns, so the answers are those of episodes run
alone.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

import torch


class Turns:
    """Whose turn it is among ``n`` threads (round robin over those not yet done)."""

    def __init__(self, n: int):
        self._cond = threading.Condition()
        self._turn, self._done = 0, [False] * n

    def wait(self, i: int) -> None:
        with self._cond:
            self._cond.wait_for(lambda: self._turn == i)

    def hand_on(self, i: int, done: bool = False) -> None:
        """Thread ``i`` ends its turn (``done``: and every later one)."""
        with self._cond:
            self._done[i] = self._done[i] or done
            n = len(self._done)
            for k in range(1, n + 1):
                if not self._done[(i + k) % n]:
                    self._turn = (i + k) % n
                    break
            self._cond.notify_all()


class TakingTurns:
    """A policy (``reset``, ``act``) that runs ``steps`` steps in each of thread ``i``'s turns."""

    def __init__(self, policy, turns: Turns, i: int, steps: int):
        self.policy, self.turns, self.i, self.steps, self.calls = policy, turns, i, steps, 0

    def reset(self, state, goals) -> None:
        self.turns.wait(self.i)
        self.policy.reset(state, goals)

    def act(self, state, goals, t):
        if self.calls and self.calls % self.steps == 0:
            self.turns.hand_on(self.i)
            self.turns.wait(self.i)
        self.calls += 1
        return self.policy.act(state, goals, t)


def run_in_lockstep(episodes: list[Callable[[Callable], object]], steps: int = 1) -> list[tuple[object, float]]:
    """``episode(wrap)`` runs one episode with the policy ``wrap(policy)`` and returns its result;
    returns ``(result, thread CPU seconds)`` per episode, the episodes run in lockstep, ``steps``
    policy steps a turn (module docstring). Setup before the first policy step is timed as well,
    outside the turns."""
    turns = Turns(len(episodes))
    out: list = [None] * len(episodes)

    def body(i: int) -> None:
        try:
            with torch.no_grad():   # grad mode is per thread
                t0 = time.thread_time()
                result = episodes[i](lambda policy: TakingTurns(policy, turns, i, steps))
                out[i] = (result, time.thread_time() - t0)
        except BaseException as exc:   # noqa: BLE001 - raised again in the calling thread
            out[i] = exc
        finally:
            turns.hand_on(i, done=True)

    threads = [threading.Thread(target=body, args=(i,)) for i in range(len(episodes))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for o in out:
        if isinstance(o, BaseException):
            raise RuntimeError("an episode in lockstep failed") from o
    return out
