"""Tuning of identification (Sec. III-A): `IdentificationConfig`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

Probe = Literal["darken_one", "light_one"]


@dataclass(frozen=True)
class IdentificationConfig:
    """Tuning of identification.

    Attributes:
        landmarks_needed: identify this many, then light all (2 in the paper).
        probe: what `next_request` asks for: "darken_one" (every LED lit but the
            candidate: other robots keep tracking) or "light_one" (the paper: a dark
            ceiling with the candidate alone lit).
        frames_per_led: frames with a candidate switched without evidence before it is
            skipped.
        led_timeout_s: a requested LED change not confirmed within this is skipped, seconds.
        match_radius_px: a spot within this of a spot of the other frame (plus the image
            motion in between) is the same source, pixels.
        inner_radius_fraction: only changed spots within this fraction of the distance from
            the principal point to the nearest image edge are used (at the edge of the view,
            spots fade in and out with the robot's motion and flicker at the threshold),
            minus the image motion.
        min_relative_intensity: only changed spots at least this bright relative to the
            median spot of their frame are used (a faint spot flickers at the threshold).
        unique_brightness_ratio: with several changed spots, the brightest is taken only
            when it is this many times brighter than the next.
        reference_max_age_s: frames further apart than this are not compared, seconds
            (two opposite pieces of evidence pair only within twice this; older unpaired
            evidence is dropped).
        follow_window_s: a sighting against a lit ceiling is confirmed only if the spot
            followed its LED in every kept frame from this long before its first piece of
            evidence to this long after its last, seconds.
        history_frames: frames kept for comparisons.
        max_reprobes: a landmark that showed itself on one side only and is lit again is
            darkened again at once, at most this many times a round (darken_one).
        led_settle_frames: the first this many frames stamped after an LED change are no
            evidence: the exposure of a frame stamped after the switch may have begun before
            it, or, with stamps taken on arrival (late by up to a frame interval), ended
            before it.
        led_settle_s: ... nor any frame stamped less than this after the change (a long
            exposure at a high frame rate, the LED's own rise), seconds.
        command_latency_s: the prior of the time from a probe's request to its confirmed
            switch (measured from then on), seconds.
        latency_smoothing: weight of each new latency sample (exponential average).
        view_headings: headings sampled around the one landmark identified, to predict
            which candidates are in view when the next probe lands.
        reorder_distance_m: with one landmark identified, order the candidates again by
            view after the robot drove this far, metres.
        reorder_turn_rad: ... or turned this far, radians.
    """

    landmarks_needed: int = 2
    probe: Probe = "darken_one"
    frames_per_led: int = 2
    led_timeout_s: float = 0.5
    match_radius_px: float = 3.0
    inner_radius_fraction: float = 0.8
    min_relative_intensity: float = 0.5
    unique_brightness_ratio: float = 2.0
    reference_max_age_s: float = 0.5
    follow_window_s: float = 0.1
    history_frames: int = 24
    max_reprobes: int = 2
    led_settle_frames: int = 1
    led_settle_s: float = 0.02
    command_latency_s: float = 0.3
    latency_smoothing: float = 0.3
    view_headings: int = 72
    reorder_distance_m: float = 0.3
    reorder_turn_rad: float = 0.52

    def __post_init__(self) -> None:
        if (
            self.landmarks_needed < 2
            or self.frames_per_led < 1
            or self.history_frames < 2
            or self.view_headings < 1
            or self.max_reprobes < 0
        ):
            raise ValueError(
                "IdentificationConfig: landmarks_needed >= 2, frames_per_led >= 1, "
                "history_frames >= 2, view_headings >= 1, max_reprobes >= 0"
            )
        if self.probe not in ("darken_one", "light_one"):
            raise ValueError(
                f"IdentificationConfig.probe: 'darken_one' or 'light_one', got {self.probe!r}"
            )
        if self.unique_brightness_ratio < 1.0:
            raise ValueError(
                "IdentificationConfig.unique_brightness_ratio must be >= 1, "
                f"got {self.unique_brightness_ratio}"
            )
        if self.led_settle_frames < 0 or not 0 <= self.led_settle_s < self.led_timeout_s:
            raise ValueError(
                "IdentificationConfig: led_settle_frames >= 0, 0 <= led_settle_s < "
                f"led_timeout_s, got {self.led_settle_frames}, {self.led_settle_s}"
            )
        if self.command_latency_s < 0 or not 0 < self.latency_smoothing <= 1:
            raise ValueError(
                "IdentificationConfig: command_latency_s >= 0 and 0 < latency_smoothing <= 1, "
                f"got {self.command_latency_s}, {self.latency_smoothing}"
            )
