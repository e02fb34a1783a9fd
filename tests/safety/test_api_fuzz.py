"""Every operation of the console's OpenAPI document, fuzzed by schemathesis against a real
``teleprog up`` (telerobot, link and console as processes on loopback): no request of any shape
answers 5xx, and every answer has a status, a content type and a body the document declares.

Each operation gets a few bodies, parameters and headers that fit the document and a few that
do not (schemathesis' positive and negative modes), without shrinking (a failure names the
request that made it): about a minute in all. Schemathesis' pytest plugin does not run on this
pytest, so the operations are walked here, each as its own hypothesis run, and every failing
operation is reported, not just the first. The fuzz may take the control lock
(``/api/control/request`` or ``/takeover`` with a random name); the token it got is presented
on the calls after it, so the operations after it are exercised past the lock instead of all
answering 409.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from schemathesis.checks import content_type_conformance, not_a_server_error, response_schema_conformance, status_code_conformance
from schemathesis.generation import GenerationMode

from support import RunningConsole, start_console, stop_process

EXAMPLES_PER_OPERATION = 10
CHECKS = [not_a_server_error, status_code_conformance, content_type_conformance, response_schema_conformance]


@pytest.fixture(scope="module")
def fuzzed_console(tmp_path_factory) -> Iterator[RunningConsole]:
    running = start_console(tmp_path_factory.mktemp("fuzz"), "--delay-ms", "20")
    try:
        yield running
    finally:
        stop_process(running.proc)


class Holder:
    """The control token the fuzz last obtained, presented on every later call."""

    def __init__(self) -> None:
        self.headers: dict[str, str] = {}

    def take_from(self, case, response) -> None:
        if case.path in ("/api/control/request", "/api/control/takeover") and response.status_code == 200:
            body = response.json()
            self.headers = {"X-Teleprog-Client": body["holder"], "X-Teleprog-Token": body["token"]}


def fuzz_operation(operation, url: str, holder: Holder) -> None:
    """Raise (the first check that failed, with the request) if any generated call fails."""
    cases = st.one_of(operation.as_strategy(GenerationMode.POSITIVE), operation.as_strategy(GenerationMode.NEGATIVE))

    @given(case=cases)
    @settings(
        max_examples=EXAMPLES_PER_OPERATION, deadline=None, derandomize=True, database=None,
        phases=[Phase.explicit, Phase.generate], suppress_health_check=list(HealthCheck), report_multiple_bugs=False,
    )
    def run(case) -> None:
        response = case.call(base_url=url, headers=dict(holder.headers), timeout=30)
        holder.take_from(case, response)
        case.validate_response(response, checks=CHECKS)

    run()


def test_no_operation_answers_5xx_or_off_schema(fuzzed_console: RunningConsole) -> None:
    schema = schemathesis.openapi.from_url(fuzzed_console.url + "/openapi.json")
    holder = Holder()
    operations = [result.ok() for result in schema.get_all_operations()]
    assert len(operations) > 40, "the console's OpenAPI document lost its operations"
    failures: list[str] = []
    for operation in operations:
        try:
            fuzz_operation(operation, fuzzed_console.url, holder)
        except (Exception, BaseExceptionGroup) as exc:  # noqa: BLE001 - collected, reported together below
            failures.append(f"{operation.method.upper()} {operation.path}: {str(exc).strip()[:1500]}")
    assert not failures, f"{len(failures)} of {len(operations)} operations failed:\n\n" + "\n\n".join(failures)
