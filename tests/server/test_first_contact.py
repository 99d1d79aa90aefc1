"""What a new user meets first: the home page, offline API docs, the console's links."""

from __future__ import annotations

import re
from pathlib import Path

from server.console import browser_host, leds_line, startup_lines
from tests.server.conftest import Api


def test_home_page_links_the_viewer_docs_and_health(api: Api) -> None:
    r = api.client.get("/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    links = set(re.findall(r'href="([^"]+)"', r.text))
    assert {"/viewer/", "/docs", "/redoc", "/healthz", "/openapi.json"} <= links
    assert "running: 0 robots, 0 landmarks, radio absent" in r.text
    assert f"--data-dir\n{api.services.settings.data_dir}" in r.text
    assert "/api/v1/metrics" in r.text and "http" not in r.text.split("<body>")[1]


def test_api_docs_load_nothing_from_outside(api: Api) -> None:
    for page in ("/docs", "/redoc"):
        html = api.client.get(page).text
        urls = re.findall(r'(?:src|href|url)\s*[:=]\s*["\']([^"\']+)["\']', html)
        assert urls, page
        assert all(u.startswith("/") for u in urls), (page, urls)
        for u in urls:
            if "static" in u:
                asset = api.client.get(u)
                assert asset.status_code == 200 and len(asset.content) > 1000, u


def test_console_prints_a_ready_to_click_viewer_url() -> None:
    lines = startup_lines(
        host="0.0.0.0", port=8000, data_dir=Path("/srv/irloc"), viewer_enabled=True,
        first_key="irloc_abc",
    )  # fmt: skip
    assert "irloc: viewer    http://127.0.0.1:8000/viewer/?token=irloc_abc" in lines
    assert "irloc: home      http://127.0.0.1:8000/" in lines
    later = startup_lines(
        host="127.0.0.1", port=9000, data_dir=Path("/srv/irloc"), viewer_enabled=True,
        first_key=None,
    )  # fmt: skip
    viewer = next(line for line in later if "viewer" in line)
    assert "<key>" not in viewer and "token=KEY" in viewer
    assert "irloc keys create --role viewer --data-dir /srv/irloc" in viewer
    assert browser_host("::1") == "[::1]"


def test_console_says_how_the_leds_run_and_how_to_change_it() -> None:
    line = leds_line("scheduled", 0.5)
    assert "only what the robots need" in line and "every 0.5 s" in line
    assert "IRLOC_LED_POLICY=all_lit" in line
    assert "awake radios" in leds_line("scheduled", None)
    line = leds_line("all_lit", None)
    assert "every LED lit" in line and "IRLOC_LED_POLICY=scheduled" in line
