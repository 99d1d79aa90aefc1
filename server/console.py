"""What `irloc serve` prints at start: where the data is, and links ready to click."""

from __future__ import annotations

import ipaddress
from pathlib import Path

WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def browser_host(host: str) -> str:
    """The address a browser on this machine opens for a server bound to `host` (a
    wildcard bind is reached at 127.0.0.1; IPv6 literals get brackets)."""
    if host in WILDCARD_HOSTS:
        return "127.0.0.1"
    try:
        if ipaddress.ip_address(host).version == 6:
            return f"[{host}]"
    except ValueError:
        pass
    return host


def leds_line(led_policy: str, radio_sleep_period_s: float | None) -> str:
    """How the landmarks' LEDs and radios run, and the setting that changes it."""
    if led_policy == "scheduled":
        radios = (
            "awake radios"
            if radio_sleep_period_s is None
            else f"radios asleep between wake-ups every {radio_sleep_period_s:g} s"
        )
        how = f"only what the robots need lit, {radios}"
        other = "IRLOC_LED_POLICY=all_lit: every LED lit"
    else:
        how = "every LED lit, the paper's way"
        other = "IRLOC_LED_POLICY=scheduled: only what the robots need"
    return f"irloc: LEDs      {how} ({other}; docs/server.md, the LED schedule)"


def startup_lines(
    *,
    host: str,
    port: int,
    data_dir: Path,
    viewer_enabled: bool,
    first_key: str | None,
) -> list[str]:
    """The console lines: home page, API docs and the viewer's URL, with the key in it when
    the key was just created (shown once), else how to get one."""
    base = f"http://{browser_host(host)}:{port}"
    lines = [
        f"irloc: data in {data_dir}",
        f"irloc: home      {base}/",
        f"irloc: API docs  {base}/docs",
    ]
    if viewer_enabled:
        if first_key is not None:
            lines.append(f"irloc: viewer    {base}/viewer/?token={first_key}")
        else:
            lines.append(
                f"irloc: viewer    {base}/viewer/?token=KEY  with KEY an API key of this site "
                f"(irloc keys create --role viewer --data-dir {data_dir})"
            )
    if first_key is not None:
        lines.append(f"irloc: first admin API key (shown once, store it): {first_key}")
    return lines
