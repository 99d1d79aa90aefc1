"""A panel's status line: what the last action did, cleared a while after it.

A line such as "zone **dock** saved" or "**refused**: ..." that stayed on screen read as
the present state minutes later (it outlived its action). `StatusLine.say` shows it and
`refresh`, called with the panels' refresh (2 Hz), clears it `ttl_s` after.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import viser


class StatusLine:
    """Wraps a panel's status markdown.

    Args:
        handle: the markdown the status is written to.
        ttl_s: how long a status stays, seconds.
        clock: monotonic seconds (tests pass their own).
    """

    def __init__(
        self,
        handle: viser.GuiMarkdownHandle,
        *,
        ttl_s: float = 20.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.handle, self.ttl_s, self.clock = handle, ttl_s, clock
        self._since: float | None = None

    def say(self, text: str) -> None:
        """Show `text` for `ttl_s`."""
        self.handle.content = text
        self._since = self.clock() if text else None

    def refresh(self) -> bool:
        """Clear an expired status; True when it did."""
        if self._since is None or self.clock() - self._since < self.ttl_s:
            return False
        self.handle.content = ""
        self._since = None
        return True
