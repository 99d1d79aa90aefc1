"""The DDS domain of this test run: one per process (pytest-xdist workers and runs side by
side do not meet), loopback only (the machine has no network)."""

from __future__ import annotations

import os

DOMAIN_ID = 100 + os.getpid() % 100
