from __future__ import annotations

import asyncio

import pytest

from rf_gateway.waiters import SeqWaiters


def test_confirming_a_newer_sequence_answers_the_older_waiters() -> None:
    async def main() -> None:
        w = SeqWaiters()
        old, mid, new, other = w.add(1, 3), w.add(1, 5), w.add(1, 8), w.add(2, 4)
        w.resolve(1, 5, 1234)
        assert (old.result(), mid.result()) == (1234, 1234)
        assert not new.done() and not other.done()
        w.fail(1, 8, RuntimeError("landmark 1 gone"))
        with pytest.raises(RuntimeError, match="landmark 1 gone"):
            new.result()
        w.fail_all(ValueError("closed"))
        with pytest.raises(ValueError, match="closed"):
            other.result()

    asyncio.run(main())
