"""How a trial talks to a session, in real or in virtual time: one interface, two drivers.

A trial's procedure (``server.trials.approach``, ``server.trials.kinds``) is written once against
:class:`Driver`: submit statements (one at a time as they are generated, or a previewed block),
wait for their final reports, read the clock. The drivers:

- :class:`ApiDriver` (``--clock real``): a real ``teleprog up`` session (``server.trials.session``),
  driven through the console's HTTP API; the clock is the console's (Unix seconds).
- ``server.trials.virtual_clock.VirtualDriver`` (``--clock virtual``): the console's command
  sender and planner, the delayed link and the telerobot, all sans-I/O in this process on one
  virtual clock stepped by the robot's servo period.

Both return :class:`SentRecord` for each statement, with the console's times (submitted, final
report arrived) and the robot's own clock (``robot_run_s``: running -> final on the robot).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal, Protocol

from server.trials.session import ConsoleApi, TrialError, wait_until

Clock = Literal["real", "virtual"]
FINAL = frozenset({"done", "failed", "skipped", "aborted", "rejected", "unknown"})
POLL_S = 0.02  # how often the real driver reads /api/sent while it waits for a report


@dataclass
class SentRecord:
    """One submitted statement as the trial saw it (times on the driver's clock, s)."""

    id: int
    text: str
    planned_s: float  # the console's planned duration: the virtual robot's time for it
    status: str = "sending"
    reason: str | None = None
    submitted_at: float = 0.0
    finished_at: float | None = None
    run_s: float | None = None  # running report -> final report, on the console's clock
    robot_run_s: float | None = None  # the same on the robot's clock

    @property
    def final(self) -> bool:
        return self.status in FINAL


def settled(records: list[SentRecord]) -> bool:
    """Every record final, or one ended other than done (what follows it is held)."""
    return all(r.final for r in records) or any(r.final and r.status != "done" for r in records)


class Driver(Protocol):
    clock: Clock

    def now(self) -> float:
        """The driver's clock, s."""

    def wait_until(self, t: float) -> None:
        """Let the session run until the clock reads ``t`` (real: sleep; virtual: step)."""

    def generate(self, texts: list[str]) -> list[float]:
        """The operator makes ``texts`` on the virtual arm (the console plans them where the last
        one ended); their planned durations. They wait in the program until :meth:`send`.
        Raises ``TrialError`` when the console refuses one."""

    def send(self, *, previewed: bool = False) -> list[SentRecord]:
        """Submit what was generated and not sent (``previewed``: as an offline block that passed
        the console's preview). Raises ``TrialError`` when the console refuses."""

    def finals(self, records: list[SentRecord], timeout: float) -> list[SentRecord]:
        """Wait (at most ``timeout`` of the driver's clock) until every record is final, or one
        ended other than done (the robot then holds the rest and waits for the operator)."""

    def zone(self) -> str:
        """The control zone (free, quasi, operation) of the virtual arm where the program ends."""

    def one_way_delay_s(self) -> float:
        """The link's one-way delay as the console knows it."""

    def restart_at_start(self, back_to_start: str) -> None:
        """Put the arm back where the trial starts, untimed (between the modes of one run)."""


class ApiDriver:
    """A real session through its HTTP API. A submit takes the statements out of the program, so
    what is generated and unsent is always the whole program. The console's editor takes nothing
    after a task call (thesis §4.3.6): generating past a task first sends what waits."""

    clock: Clock = "real"

    def __init__(self, api: ConsoleApi, delay_s: float) -> None:
        self.api = api
        self.delay_s = delay_s
        self._pending: list[tuple[str, float]] = []
        self._previewed = False
        self._sent_early: list[SentRecord] = []
        self.api.call("PUT", "/api/program/auto", {"on": False})

    def now(self) -> float:
        return time.time()

    def wait_until(self, t: float) -> None:
        time.sleep(max(0.0, t - time.time()))

    def generate(self, texts: list[str]) -> list[float]:
        planned = []
        for text in texts:
            if self._pending and self._pending[-1][0].lstrip().upper().startswith("TASK"):
                self._sent_early += self._send_pending(self._previewed)
            program = self.api.call("POST", "/api/program/insert", {"text": text})
            duration = program["entries"][len(self._pending)]["duration_s"] or 0.0
            self._pending.append((text, duration))
            planned.append(duration)
        return planned

    def send(self, *, previewed: bool = False) -> list[SentRecord]:
        self._previewed = previewed
        records, self._sent_early = self._sent_early + self._send_pending(previewed), []
        return records

    def _send_pending(self, previewed: bool) -> list[SentRecord]:
        if not self._pending:
            return []
        n = len(self._pending)
        if previewed:
            self.api.call("POST", "/api/preview/speed", {"speed": "instant"})
            answer = self.api.call("POST", "/api/preview/submit", {"start": 0, "stop": n})
            if not answer["submitted"]:
                raise TrialError(f"the preview did not send statements 1..{n}: {answer['message']}")
            items = answer["sent"]["items"]
        else:
            items = self.api.call("POST", "/api/submit", {"start": 0, "stop": n})["items"]
        records = [SentRecord(id=s["id"], text=s["text"], planned_s=p, status=s["status"], submitted_at=s["submitted_at"])
                   for s, (_, p) in zip(items[-n:], self._pending, strict=True)]
        self._pending = []
        return records

    def finals(self, records: list[SentRecord], timeout: float) -> list[SentRecord]:
        ids = {r.id: r for r in records}

        def all_final():
            items = {s["id"]: s for s in self.api.call("GET", "/api/sent")["items"] if s["id"] in ids}
            for i, s in items.items():
                r = ids[i]
                r.status, r.reason, r.finished_at = s["status"], s["reason"], s["finished_at"]
                r.run_s, r.robot_run_s = s["run_s"], s.get("robot_run_s")
            return settled(records)

        wait_until(all_final, timeout, f"final reports of statements {sorted(ids)}", POLL_S)
        return records

    def zone(self) -> str:
        return self.api.call("GET", "/api/regime")["zone"]

    def one_way_delay_s(self) -> float:
        measured = self.api.call("GET", "/api/link")["delay_s"]
        return measured if measured is not None else self.delay_s

    def restart_at_start(self, back_to_start: str) -> None:
        self.generate([back_to_start])
        (record,) = self.send()
        self.finals([record], 2 * self.delay_s + 60.0)
        if record.status != "done":
            raise TrialError(f"going back to the start: {record.status}: {record.reason}")
        wait_until(lambda: self.api.call("GET", "/api/remote")["state"] == "idle", 10.0 + 2 * self.delay_s,
                   "the telerobot idle")
        if self.api.call("GET", "/api/divergence")["diverged"]:
            self.api.call("POST", "/api/resync")
