"""The API's documentation renders on an isolated network: Swagger UI and ReDoc come from the
console's own files (issue 16, finding 8). Every request the page makes outside loopback is
refused and recorded; the pages must render their operations with none attempted."""

from __future__ import annotations

from urllib.parse import urlparse

import pytest

pytestmark = pytest.mark.browser


def offline(page) -> list[tuple[str, str]]:
    """Abort every request that leaves the machine; return those attempted (type, URL)."""
    outside: list[tuple[str, str]] = []

    def route(r):
        host = urlparse(r.request.url).hostname
        if host in ("127.0.0.1", "localhost"):
            r.continue_()
        else:
            outside.append((r.request.resource_type, r.request.url))
            r.abort()

    page.route("**/*", route)
    return outside


def test_swagger_ui_renders_the_operations_with_no_network(console, page):
    outside = offline(page)
    page.goto(console.url + "/docs")
    page.wait_for_selector(".opblock", timeout=60_000)
    paths = page.eval_on_selector_all(".opblock-summary-path", "els => els.map(e => e.textContent)")
    assert "/api/health" in [p.replace("\u200b", "") for p in paths]
    assert page.locator(".swagger-ui .info .title").inner_text().startswith("teleprog console")
    assert outside == []


def test_redoc_renders_with_no_network(console, page):
    outside = offline(page)
    page.goto(console.url + "/redoc")
    # ReDoc breaks long paths with zero-width spaces
    page.wait_for_function("document.body.innerText.replace(/\\u200b/g, '').includes('/api/health')", timeout=60_000)
    assert "teleprog console" in page.locator("h1").first.inner_text()
    # ReDoc's footer asks cdn.redoc.ly for its logo: an image, nothing the page needs
    assert [url for kind, url in outside if kind != "image"] == []
