"""Prometheus metrics, read from the services at scrape time (own registry per app)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from prometheus_client import CollectorRegistry, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, Metric
from prometheus_client.registry import Collector
from starlette.datastructures import State

from live.leds.status import energy_metrics
from server.metrics_reliability import reliability_metrics

if TYPE_CHECKING:
    from live.services import SiteServices
    from server.fanout import PoseFanout


class SiteCollector(Collector):
    """Poses per robot, pose-bus drops, radio queue and failures, HTTP errors, and the
    reliability counters (`server.metrics_reliability`)."""

    def __init__(self, services: SiteServices) -> None:
        self.services = services
        self.http_errors: dict[str, int] = {}
        self.fanout: PoseFanout | None = None
        self.app_state: State | None = None
        """The app's state: the edge guard's counters, the connection guard, the bad-key
        throttle, the MQTT bridge (`server.metrics_reliability`)."""

    def collect(self) -> Iterator[Metric]:
        s = self.services
        poses = CounterMetricFamily("irloc_poses", "pose estimates computed", labels=["robot"])
        frames = CounterMetricFamily("irloc_frames", "frames fed to localizers", labels=["robot"])
        errs = CounterMetricFamily(
            "irloc_localizer_errors", "localizer exceptions", labels=["robot"]
        )
        reasons = CounterMetricFamily(
            "irloc_pose_reasons",
            "poses per reason they are no landmark fix (landmark_fix: those that are)",
            labels=["robot", "reason"],
        )
        for r in s.robots.runners():
            poses.add_metric([r.name], r.poses)
            frames.add_metric([r.name], r.frames)
            errs.add_metric([r.name], r.errors)
            for reason, n in sorted(r.reasons.counts().items()):
                reasons.add_metric([r.name, reason], n)
        yield poses
        yield reasons
        yield frames
        yield errs
        yield CounterMetricFamily(
            "irloc_pose_bus_published", "pose bus items", value=s.poses.published
        )
        yield CounterMetricFamily(
            "irloc_pose_bus_dropped",
            "pose bus items dropped for slow subscribers",
            value=s.poses.dropped,
        )
        yield GaugeMetricFamily(
            "irloc_pose_subscribers", "pose bus subscribers", value=len(s.poses)
        )
        fan = self.fanout
        if fan is not None:
            yield GaugeMetricFamily(
                "irloc_ws_clients", "pose WebSocket clients", value=len(fan.clients)
            )
            yield CounterMetricFamily(
                "irloc_ws_dropped_poses",
                "poses dropped for WebSocket clients that fell behind",
                value=fan.dropped_poses,
            )
        gw = s.leds.gateway
        if gw is not None:
            yield CounterMetricFamily(
                "irloc_radio_commands", "radio commands sent", value=gw.stats.commands
            )
            yield CounterMetricFamily(
                "irloc_radio_retries", "radio retries", value=gw.stats.retries
            )
            yield CounterMetricFamily(
                "irloc_radio_failures", "radio commands that failed", value=gw.stats.failures
            )
            yield GaugeMetricFamily(
                "irloc_landmarks_unreachable", "unreachable landmarks", value=len(gw.unreachable)
            )
        site = s.runner
        wheel_lines = CounterMetricFamily(
            "irloc_wheel_lines", "serial wheel-speed lines fed to robots", labels=["robot"]
        )
        wheel_bad = CounterMetricFamily(
            "irloc_wheel_bad_lines", "serial wheel-speed lines skipped", labels=["robot"]
        )
        for name, src in sorted((site.wheels if site is not None else {}).items()):
            wheel_lines.add_metric([name], src.lines)
            wheel_bad.add_metric([name], src.bad_lines)
        yield wheel_lines
        yield wheel_bad
        yield from energy_metrics(s)
        coordinator = s.leds.coordinator
        waiting = 0 if coordinator is None else coordinator.waiting
        yield GaugeMetricFamily("irloc_radio_queue", "LED requests waiting", value=waiting)
        http = CounterMetricFamily("irloc_http_errors", "HTTP error answers", labels=["status"])
        for code, n in sorted(self.http_errors.items()):
            http.add_metric([code], n)
        yield http
        yield from reliability_metrics(s, self.app_state)


def make_registry(services: SiteServices) -> tuple[CollectorRegistry, SiteCollector]:
    registry = CollectorRegistry(auto_describe=False)
    collector = SiteCollector(services)
    registry.register(collector)
    return registry, collector


def render(registry: CollectorRegistry) -> bytes:
    return generate_latest(registry)
