"""Helpers of the viewer tests (imported by ``conftest.py`` and the test modules)."""


def open_page(b, url, ready="window.envcap.ready"):
    """Point the Chromium ``b`` (:class:`envcap.viewer.browser.Chromium`) at ``url`` with no errors
    recorded and wait for the page's promise ``ready`` (an error fails the test with the page's
    errors); returns ``b``."""
    b.errors.clear()
    b.goto(url)
    assert b.evaluate(f"{ready}.then(() => 'ok', e => 'error: ' + e.message)") == "ok", b.errors
    return b
