"""Start-up trace: what each process of ``teleprog up`` reached, and when (wall clock).

Off unless ``TELEPROG_STARTUP_TRACE`` is set in the environment (children inherit it). Each mark
is one log line on stderr, ``startup-trace <process> <unix time, s> <event>``, which
``benchmarks/bench_startup.py`` reads to time the phases across the console, the telerobot and
the link. Stdlib only: the console marks before its heavy imports.
"""

from __future__ import annotations

import logging
import os
import time

log = logging.getLogger("teleprog.startup")

ENV = "TELEPROG_STARTUP_TRACE"
PREFIX = "startup-trace"


def enabled() -> bool:
    return bool(os.environ.get(ENV))


def mark(process: str, event: str) -> None:
    """Log that ``process`` (``console``, ``robot``, ``link``) reached ``event`` now, if tracing."""
    if enabled():
        log.info("%s %s %.6f %s", PREFIX, process, time.time(), event)
