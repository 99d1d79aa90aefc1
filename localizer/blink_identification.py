"""Identification by switching LEDs, as the localizer drives it (paper Sec. III-A).

The `Identifier` gathers the evidence (spots that follow an LED's switching) and plans the
probes; this object adds what the localizer knows around it: the order the candidates are
probed in (first those in view of where the robot will be when the next probe lands,
`candidate_order`), the candidates restarted nearest first around a pose, and the first fix
from two or more identified landmarks, each carried by odometry to the frame's time
(`first_fix`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from localizer.camera import CameraModel
from localizer.candidate_order import ViewOrdering, order_by_view
from localizer.config import LocalizerConfig
from localizer.events import LedRequest
from localizer.first_fix import first_fix
from localizer.identification import Identifier
from localizer.landmark_map import LandmarkMap
from localizer.led_knowledge import LedKnowledge
from localizer.odometry import integrate_arc
from localizer.odometry_track import OdometryTrack
from localizer.pose import PoseFix


class BlinkIdentification:
    """The identifier, the candidates' order by view, and the first fix (module docstring).

    Args:
        config: the localizer's tuning (`identification`, `fusion`).
        odometry: the raw dead-reckoning track (stored with each piece of evidence).
        wheel_base: metres (where the robot will be when a probe lands).

    Attributes:
        identifier: the current map's `Identifier` (set by `set_map`).
    """

    def __init__(self, config: LocalizerConfig, odometry: OdometryTrack, wheel_base: float):
        self.config = config
        self._odometry = odometry
        self._wheel_base = wheel_base
        ic = config.identification
        # the sighting the candidates were last ordered from, and the raw odometry then
        self._view = ViewOrdering(ic.reorder_distance_m, ic.reorder_turn_rad)

    def set_map(
        self,
        landmark_map: LandmarkMap,
        camera: CameraModel,
        motion_px: Callable[[int, int], float],
    ) -> None:
        """A new map (and the camera's image): a new identifier. `motion_px` bounds a
        spot's image motion between two times (`Identifier`)."""
        self.map = landmark_map
        self.identifier = Identifier(
            self.config.identification,
            landmark_map.ids.tolist(),
            positions=landmark_map.positions,
            image_size=(camera.width, camera.height),
            principal_point=(camera.cu, camera.cv),
            motion_px=motion_px,
            odometry_at=self._odometry.pose_at,
        )

    def restart(self, near: tuple[float, float] | None) -> None:
        """Identification starts over; the candidates nearest to `near` (x, y metres; None:
        the map's order) first."""
        ids = self.map.ids.tolist()
        if near is not None:
            x, y = near
            d = np.hypot(self.map.positions[:, 0] - x, self.map.positions[:, 1] - y)
            ids = [int(self.map.ids[i]) for i in np.argsort(d, kind="stable")]
        self.identifier.restart(ids)
        self._view.reset()

    def first_fix(self, t_ns: int, camera: CameraModel) -> PoseFix | None:
        """First fix from identified landmarks, each carried by odometry to the frame time."""
        sightings = list(self.identifier.sightings.values())
        if len(sightings) < self.config.identification.landmarks_needed:
            return None
        fc = self.config.fusion
        fix = first_fix(
            camera,
            self.map,
            sightings,
            self._odometry.pose_at,
            t_ns,
            pixel_sigma_px=fc.pixel_sigma_px,
            max_residual_px=fc.max_residual_px,
        )
        if fix is None:
            # Inconsistent sightings: keep the newest (a fresh one, near the robot), find
            # another in view of it.
            self.identifier.keep_newest()
            self._view.reset()
        return fix

    def requests(
        self, t_ns: int, leds: LedKnowledge, camera: CameraModel, frame_interval_s: float | None
    ) -> list[LedRequest]:
        """LED requests of an identification in progress (the last one lights all): the
        next probe of the sweep `leds` keeps, its candidates first ordered by view."""
        req = leds.all_lit_request(t_ns)
        if req is not None:
            return [req]
        if not leds.sweeping:
            return []
        self.order_by_view(t_ns, camera, frame_interval_s)
        return list(leds.sweep_request(t_ns, self.identifier))

    def order_by_view(self, t_ns: int, camera: CameraModel, frame_interval_s: float | None) -> None:
        """With one landmark identified (or showing itself), probe first the candidates in
        view of where the robot can be when the next probe lands (`order_by_view`: the
        sighting's ray from its odometry pose, the odometry since, extrapolated at the
        current wheel speeds over the measured command latency and the frames a probe
        needs); again once odometry has moved `reorder_distance_m` or turned
        `reorder_turn_rad` since the last ordering."""
        identifier = self.identifier
        anchor = identifier.anchor
        if anchor is None or anchor.landmark_id not in self.map:
            return
        ic = self.config.identification
        track = self._odometry
        odo = track.pose_at(t_ns)
        if not self._view.due(anchor, odo):
            return
        frame_s = frame_interval_s or 0.0
        lead_s = identifier.probes.latency_s + ic.frames_per_led * frame_s
        x, y, th = track.pose
        landing = integrate_arc(x, y, th, *track.speeds, lead_s, self._wheel_base)
        then = anchor.odometry or track.pose_at(anchor.t_ns)
        ranked = order_by_view(
            camera,
            self.map.ids.tolist(),
            self.map.positions,
            anchor.landmark_id,
            anchor.pixel,
            then,
            landing,
            headings=ic.view_headings,
            inner_radius_px=identifier.inner_radius_px,
        )
        order, fresh = self._view.ordered(anchor, odo, ranked)
        identifier.prefer(order, come_into_view=fresh)
