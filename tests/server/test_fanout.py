"""The WebSocket fan-out: one encoding per batch and filter, bounded client queues."""

from __future__ import annotations

import asyncio
import json

import numpy as np

from live.poses import PoseUpdate
from pubsub.bus import Bus
from server.fanout import FanoutClient, PoseFanout, encode_batch


def _pose(robot: str, i: int) -> PoseUpdate:
    return PoseUpdate(robot, i, "landmark", 0.5 * i, -0.25 * i, 0.1, np.eye(3) * 1e-4, (3,))


def test_batch_is_encoded_once_and_shared_by_unfiltered_clients() -> None:
    async def run() -> tuple[list[str | None], str | None]:
        fan = PoseFanout(Bus(), flush_s=0.0)
        everyone = [fan.add_client() for _ in range(3)]
        only_r2 = fan.add_client(["r2"])
        fan.dispatch([_pose("r1", 1), _pose("r2", 2), _pose("r1", 3)])
        return [await c.get() for c in everyone], await only_r2.get()

    msgs, filtered = asyncio.run(run())
    assert msgs[0] is msgs[1] is msgs[2]  # the same string object: encoded once
    assert [(p["robot"], p["t_ns"]) for p in json.loads(msgs[0] or "")] == [
        ("r1", 1),
        ("r2", 2),
        ("r1", 3),
    ]
    got = json.loads(filtered or "")
    assert [p["t_ns"] for p in got] == [2]
    np.testing.assert_allclose([got[0]["x"], got[0]["y"]], [1.0, -0.5])


def test_client_that_falls_behind_drops_oldest_messages_and_counts_poses() -> None:
    async def run() -> tuple[FanoutClient, FanoutClient, PoseFanout, list[str]]:
        fan = PoseFanout(Bus(), flush_s=0.0)
        slow = fan.add_client(maxsize=2)
        fast = fan.add_client(maxsize=100)
        for i in range(5):
            fan.dispatch([_pose("r1", 2 * i), _pose("r2", 2 * i + 1)])
        left = [await slow.get(), await slow.get()]
        return slow, fast, fan, [m for m in left if m is not None]

    slow, fast, fan, left = asyncio.run(run())
    assert [[p["t_ns"] for p in json.loads(m)] for m in left] == [[6, 7], [8, 9]]
    assert slow.dropped_poses == 6 and fast.dropped_poses == 0
    assert fan.dropped_poses == 6


def test_fanout_gathers_poses_published_from_a_thread_into_one_message() -> None:
    async def run() -> list[int]:
        bus: Bus[PoseUpdate] = Bus()
        fan = PoseFanout(bus, flush_s=0.05)
        fan.start()
        client = fan.add_client()
        loop = asyncio.get_running_loop()

        def publish_four() -> None:
            for i in range(4):
                bus.publish(_pose("r1", i))

        await loop.run_in_executor(None, publish_four)
        msg = await asyncio.wait_for(client.get(), 5)
        await fan.stop()
        assert await client.get() is None  # closed
        return [p["t_ns"] for p in json.loads(msg or "")]

    assert asyncio.run(run()) == [0, 1, 2, 3]


def test_encode_batch_is_a_json_array_of_the_pose_texts() -> None:
    poses = [_pose("a", 1), PoseUpdate("b", 2, "identifying")]
    out = json.loads(encode_batch(poses))
    assert out[1] == {
        "robot": "b",
        "t_ns": 2,
        "mode": "identifying",
        "x": None,
        "y": None,
        "theta": None,
        "covariance": None,
        "landmark_ids": [],
        "computed_wall_ns": poses[1].computed_wall_ns,
        "floor": "0",
        "map_version": 0,
        "floor_unknown": False,
        "quality": None,
        "deviation_m": None,
        "reason": None,
        "reason_text": "",
    }
