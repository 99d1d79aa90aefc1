"""The 3D scene: floor, ceiling, landmarks and robots, kept in step with site snapshots.

Node names are hierarchical: `/floor` (the one grid: 1 m cells, 5 m sections), `/ceiling`
(the ceiling's outline at its height: no second grid, so floor and ceiling never overlap
into a moire), `/floorplan` (`web.floorplan_view`), `/landmarks/17` (sphere), `/landmarks/17/label`,
`/landmarks/17/glow` (shown while lit), `/robots/r1/position` (follows the robot's position
without turning), `/robots/r1/position/body` (turns with its heading),
`/robots/r1/position/body/footprint`, `/robots/r1/position/ellipse`, `/robots/r1/trail/<k>`,
`/robots/r1/rays`, `/coverage/*`. Landmark spheres (and their glow) and robot boxes answer
clicks: `SiteScene.on_pick(client_id, kind, key)` (click-to-inspect). `/robots/<name>`
itself stays at the world origin so that the trail and rays are in world coordinates. Only
one thread (the viewer's update loop) calls `update`; it diffs against the last snapshot and
sends only what changed: a robot's pose when it has a new estimate, its ellipse when the
covariance changed by more than `ellipse_rtol`, its rays when the landmarks used changed
(else at `rays_every`), and only the newest piece of its trail.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser

from commissioning.coverage import Coverage, SpacingFlag
from localizer.types import FloatArray
from web.colors import (
    LIT_COLOR,
    RGB,
    UNKNOWN_COLOR,
    battery_color,
    landmark_color,
    mode_color,
    robot_color,
)
from web.footprint import Bounds, footprint_in_site, usable_footprint_body
from web.geometry import ellipse_points
from web.segments import polyline_segments, set_segments
from web.services import LandmarkState, RobotState
from web.trail import Trail, TrailConfig

FOOTPRINT_COLOR: RGB = (80, 160, 200)
RAY_COLOR: RGB = (250, 220, 90)
CEILING_COLOR: RGB = (170, 170, 205)
BODY_Z_M = 0.125
"""Height of a robot's box centre, metres (its scene node's origin)."""


@dataclass(frozen=True)
class SceneConfig:
    """Look of the scene.

    Attributes:
        landmark_radius_m: radius of a landmark's sphere, metres.
        trail: how trails sample poses (by distance; broken at gaps in distance or time).
        ellipse_sigma: the uncertainty ellipse's scale, standard deviations.
        ellipse_min_m: ellipses are drawn at least this large, metres (to stay visible).
        ellipse_rtol: redraw the ellipse when its covariance changed by this share.
        rays_every: redraw the rays every this many pose updates while the landmarks used
            stay the same (3: 10 Hz at 30 Hz); at once when they change.
        footprint_max_off_axis_rad: the camera footprint drawn reaches at most this far
            from the optical axis, radians (the usable angle: `commissioning.doubt.DoubtConfig`'s
            `max_off_axis_rad`; a fisheye's image border reaches far beyond it).
    """

    landmark_radius_m: float = 0.1
    trail: TrailConfig = field(default_factory=lambda: TrailConfig())
    ellipse_sigma: float = 3.0
    ellipse_min_m: float = 0.02
    ellipse_rtol: float = 0.05
    rays_every: int = 3
    footprint_max_off_axis_rad: float = math.radians(40.0)


def wxyz_from_heading(theta: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation by `theta` about world +z."""
    return (math.cos(theta / 2.0), 0.0, 0.0, math.sin(theta / 2.0))


def robot_label(name: str) -> str:
    """The text beside a robot: "robot r3" (landmark labels are bare IDs)."""
    return f"robot {name}"


def landmark_label(lm: LandmarkState) -> str:
    """The text next to a landmark: its ID, its position's 1-sigma uncertainty when the map
    knows it ("+-1.2 mm"), and "unreachable", "doubted", "(surveyed)"."""
    text = str(lm.id)
    if lm.sigma_m is not None:
        text += f" \u00b1{1000 * lm.sigma_m:.1f} mm"
    if not lm.reachable:
        text += " unreachable"
    elif lm.doubted:
        text += " doubted"
    if lm.locked:
        text += " (surveyed)"
    return text


class _RobotNodes:
    def __init__(self, scene: viser.SceneApi, name: str, cfg: SceneConfig, color: RGB) -> None:
        root = f"/robots/{name}"
        self.root = scene.add_frame(root, show_axes=False)
        at = f"{root}/position"
        self.at = scene.add_frame(at, show_axes=False, visible=False)
        self.body = scene.add_box(
            f"{at}/body",
            color=UNKNOWN_COLOR,
            dimensions=(0.45, 0.35, 0.25),
            position=(0.0, 0.0, BODY_Z_M),
        )
        self.nose = scene.add_box(
            f"{at}/body/nose",
            color=(30, 30, 30),
            dimensions=(0.15, 0.08, 0.05),
            position=(0.25, 0.0, 0.1),
        )
        # on the (unturned) position frame, beside the box and above the landmark labels'
        # side, and named as a robot: a bare "r3" over landmark "201" read "r301"
        self.label = scene.add_label(
            f"{at}/label",
            robot_label(name),
            position=(0.3, 0.3, 0.35),
            anchor="bottom-left",
            font_screen_scale=1.1,
        )
        empty = np.zeros((0, 2, 3))
        scene.add_frame(f"{root}/trail", show_axes=False)
        self.color = color
        self.trail = Trail(scene, f"{root}/trail", color=color, config=cfg.trail)
        self.ellipse = scene.add_line_segments(f"{at}/ellipse", empty, UNKNOWN_COLOR)
        self.footprint = scene.add_line_segments(f"{at}/body/footprint", empty, FOOTPRINT_COLOR)
        self.footprint_body: FloatArray | None = None  # unclipped, body frame
        self.footprint_clipped = False  # the node holds a version clipped to the site
        self.rays = scene.add_line_segments(f"{root}/rays", empty, RAY_COLOR, thickness=0.005)
        self.updates = 0
        self.mode = ""
        self.t_ns: int | None = None
        self.cov: FloatArray | None = None
        self.used: tuple[int, ...] | None = None

    def remove(self) -> None:
        self.root.remove()


class SiteScene:
    """The shared 3D scene of a viser server."""

    def __init__(self, server: viser.ViserServer, config: SceneConfig | None = None) -> None:
        self.server = server
        self.config = config or SceneConfig()
        self._landmarks: dict[int, tuple[LandmarkState, bool]] = {}
        self._spheres: dict[
            int, tuple[viser.IcosphereHandle, viser.LabelHandle, viser.IcosphereHandle]
        ] = {}
        self._robots: dict[str, _RobotNodes] = {}
        self._colors_used: list[str] = []  # robots in the order they came: their colour
        self._positions: dict[int, FloatArray] = {}
        self.ceiling_z = 2.5
        self.bounds: Bounds = (-5.0, 5.0, -5.0, 5.0)
        self.on_pick: Callable[[int, str, str], None] | None = None
        """Told of a click on a landmark or robot: (client id, "landmark" or "robot", its ID
        or name); set by the viewer (click-to-inspect)."""
        server.scene.set_up_direction("+z")

    def _picker(self, kind: str, key: str) -> Callable[[viser.SceneNodePointerEvent[Any]], None]:
        def picked(event: viser.SceneNodePointerEvent[Any]) -> None:
            if self.on_pick is not None:
                self.on_pick(event.client_id, kind, key)

        return picked

    def set_site(self, bounds: tuple[float, float, float, float], ceiling_z: float) -> None:
        """Floor grid, ceiling grid and the starting camera for a site's extent (metres)."""
        x0, x1, y0, y1 = bounds
        cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
        w, h = max(x1 - x0, 1.0), max(y1 - y0, 1.0)
        self.ceiling_z = ceiling_z
        self.bounds = (cx - w / 2.0, cx + w / 2.0, cy - h / 2.0, cy + h / 2.0)
        scene = self.server.scene
        scene.add_grid(
            "/floor",
            w,
            h,
            plane="xy",
            position=(cx, cy, 0.0),
            cell_size=1.0,
            section_size=5.0,
            cell_color=(215, 215, 215),
            section_color=(160, 160, 160),
            fade_distance=1e4,
            shadow_opacity=0.0,
        )
        bx0, bx1, by0, by1 = self.bounds
        corners = np.array(
            [[bx0, by0], [bx1, by0], [bx1, by1], [bx0, by1], [bx0, by0]], dtype=np.float64
        )
        ring = np.column_stack([corners, np.full(5, ceiling_z)])
        scene.add_line_segments("/ceiling", polyline_segments(ring), CEILING_COLOR, thickness=0.03)
        from web.camera_views import INITIAL_TOP_VIEW, apply_top_view  # near-orthographic

        apply_top_view(self.server.initial_camera, self.bounds, INITIAL_TOP_VIEW)

    # -- landmarks ---------------------------------------------------------------------------
    def update_landmarks(self, landmarks: list[LandmarkState], lit: frozenset[int]) -> None:
        """Add, move, recolour and remove landmark nodes to match `landmarks`."""
        scene = self.server.scene
        r = self.config.landmark_radius_m
        seen_ids = set()
        for lm in landmarks:
            seen_ids.add(lm.id)
            state = (lm, lm.id in lit)
            if self._landmarks.get(lm.id) == state:
                continue
            color = landmark_rgb(lm)
            pos = (lm.x, lm.y, lm.z)
            self._positions[lm.id] = np.array(pos)
            nodes = self._spheres.get(lm.id)
            if nodes is not None:  # changed in place: removing and re-adding flickers
                sphere, label, glow = nodes
                if tuple(sphere.position) != pos:
                    sphere.position = pos
                if tuple(sphere.color) != color:
                    sphere.color = color
                text = landmark_label(lm)
                if label.text != text:
                    label.text = text
                if glow.visible != (lm.id in lit):
                    glow.visible = lm.id in lit
                self._landmarks[lm.id] = state
                continue
            name = f"/landmarks/{lm.id}"
            sphere = scene.add_icosphere(name, r, color, position=pos, subdivisions=2)
            label = scene.add_label(
                f"{name}/label",
                landmark_label(lm),
                position=(0.0, 0.0, -2.0 * r),
                anchor="top-center",
                font_screen_scale=0.8,
            )
            glow = scene.add_icosphere(
                f"{name}/glow",
                2.2 * r,
                LIT_COLOR,
                opacity=0.45,
                subdivisions=2,
                visible=lm.id in lit,
                cast_shadow=False,
            )
            self._spheres[lm.id] = (sphere, label, glow)
            self._landmarks[lm.id] = state
            for node in (sphere, glow):  # the glow (larger) is what a click hits while lit
                node.on_click(self._picker("landmark", str(lm.id)))
        for gone in set(self._landmarks) - seen_ids:
            self._spheres.pop(gone)[0].remove()
            del self._landmarks[gone]
            self._positions.pop(gone, None)

    def landmark_ids(self) -> list[int]:
        """IDs of the landmarks in the scene, sorted."""
        return sorted(self._landmarks)

    def is_lit(self, landmark_id: int) -> bool:
        """Whether the landmark's glow is shown."""
        return self._landmarks[landmark_id][1]

    # -- robots ------------------------------------------------------------------------------
    def robots_changed(self, robots: list[RobotState]) -> bool:
        """Whether `update_robots` would send anything (a robot came or went, or has a new
        estimate or mode)."""
        if {r.name for r in robots} != set(self._robots):
            return True
        for rb in robots:
            nodes = self._robots[rb.name]
            t_ns = None if rb.pose is None else rb.pose.t_ns
            if rb.mode != nodes.mode or t_ns != nodes.t_ns:
                return True
        return False

    def update_robots(self, robots: list[RobotState]) -> None:
        """Move every robot and redraw its trail, ellipse, footprint and rays."""
        scene = self.server.scene
        names = {r.name for r in robots}
        for gone in set(self._robots) - names:
            self._robots.pop(gone).remove()
        for rb in robots:
            nodes = self._robots.get(rb.name)
            if nodes is None:
                color = robot_color(len(self._colors_used))
                self._colors_used.append(rb.name)
                nodes = self._robots[rb.name] = _RobotNodes(scene, rb.name, self.config, color)
                for node in (nodes.body, nodes.nose):
                    node.on_click(self._picker("robot", rb.name))
            self._update_robot(nodes, rb)

    def _update_robot(self, nodes: _RobotNodes, rb: RobotState) -> None:
        cfg = self.config
        color = mode_color(rb.mode)
        mode_changed = rb.mode != nodes.mode
        if mode_changed:
            nodes.body.color = color
            nodes.mode = rb.mode
        pose = rb.pose
        if nodes.at.visible != (pose is not None):
            nodes.at.visible = pose is not None
        if pose is None or (pose.t_ns == nodes.t_ns and not mode_changed):
            return  # no new estimate: nothing to send
        nodes.t_ns = pose.t_ns
        nodes.at.position = (pose.x, pose.y, 0.0)
        nodes.body.wxyz = wxyz_from_heading(pose.theta)
        nodes.updates += 1
        nodes.trail.append(pose.x, pose.y, pose.t_ns * 1e-9)
        cov = np.asarray(pose.covariance, dtype=np.float64)[:2, :2]
        old = nodes.cov
        if (
            mode_changed
            or old is None
            or not np.allclose(cov, old, rtol=cfg.ellipse_rtol, atol=1e-8)
        ):
            nodes.cov = cov
            c = 0.5 * (cov + cov.T) + np.eye(2) * (cfg.ellipse_min_m / cfg.ellipse_sigma) ** 2
            ring = ellipse_points((0.0, 0.0), c, n_sigma=cfg.ellipse_sigma, n_points=24)
            ring3 = np.column_stack([ring, np.full(len(ring), 0.02)])
            set_segments(nodes.ellipse, polyline_segments(ring3), color)
        rays_due = self._rays_due(nodes, tuple(pose.landmark_ids))
        self._update_footprint(nodes, rb, pose.x, pose.y, pose.theta, due=rays_due)
        if not rays_due:
            return
        cam_world = (
            np.array([pose.x, pose.y, 0.0])
            + np.array(
                [
                    [math.cos(pose.theta), -math.sin(pose.theta), 0.0],
                    [math.sin(pose.theta), math.cos(pose.theta), 0.0],
                    [0.0, 0.0, 1.0],
                ]
            )
            @ rb.camera.T_body_camera[:3, 3]
        )
        used = [self._positions[i] for i in pose.landmark_ids if i in self._positions]
        rays = np.stack([np.stack([cam_world, p]) for p in used]) if used else np.zeros((0, 2, 3))
        set_segments(nodes.rays, rays, RAY_COLOR)

    def _update_footprint(
        self, nodes: _RobotNodes, rb: RobotState, x: float, y: float, theta: float, *, due: bool
    ) -> None:
        """The usable footprint, fixed to the body (computed once, moves with it); near the
        site's edge it is clipped there, redrawn with the rays (10 Hz)."""
        first = nodes.footprint_body is None
        if nodes.footprint_body is None:
            foot = usable_footprint_body(
                rb.camera,
                self.ceiling_z,
                max_off_axis_rad=self.config.footprint_max_off_axis_rad,
            )
            foot[:, 2] -= BODY_Z_M
            nodes.footprint_body = foot
        if not (first or due):
            return
        clipped = footprint_in_site(nodes.footprint_body, x, y, theta, self.bounds)
        if clipped is None:
            if first or nodes.footprint_clipped:
                segs = polyline_segments(nodes.footprint_body)
                set_segments(nodes.footprint, segs, FOOTPRINT_COLOR)
            nodes.footprint_clipped = False
        elif first or due:
            set_segments(nodes.footprint, polyline_segments(clipped), FOOTPRINT_COLOR)
            nodes.footprint_clipped = True

    def _rays_due(self, nodes: _RobotNodes, used: tuple[int, ...]) -> bool:
        if used != nodes.used:
            nodes.used = used
            return True
        return bool(used) and nodes.updates % max(1, self.config.rays_every) == 0


def draw_coverage(
    scene: viser.SceneApi,
    coverage: Coverage | None,
    flags: list[SpacingFlag],
    positions: dict[int, FloatArray],
    *,
    by: str = "count",
) -> None:
    """Colour the floor by landmarks in view ("count") or expected error ("error").

    `scene` may be one browser's (`client.scene`). None removes the layer. Count: 0 red,
    1 amber, 2+ green. Error: green at <= 1 cm to red at >= 5 cm, red where there is no fix.
    Landmark pairs in `flags` (positions from `positions`) are joined by magenta lines.
    """
    if coverage is None:
        scene.remove_by_name("/coverage")
        return
    gx, gy = np.meshgrid(coverage.xs, coverage.ys)
    pts = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, 0.005)])
    if by == "error":
        err = coverage.error_m.ravel()
        pct = np.where(np.isnan(err), 0.0, 100.0 * np.clip((0.05 - err) / 0.04, 0.0, 1.0))
        colors = np.array([battery_color(float(p)) for p in pct], dtype=np.uint8)
    else:
        palette = np.array([(210, 40, 40), (230, 160, 20), (40, 160, 60)], dtype=np.uint8)
        colors = palette[np.clip(coverage.counts.ravel(), 0, 2)]
    scene.add_frame("/coverage", show_axes=False)
    step = float(coverage.xs[1] - coverage.xs[0]) if len(coverage.xs) > 1 else 0.25
    scene.add_point_cloud(
        "/coverage/floor",
        pts,
        colors,
        point_size=0.9 * step,
        point_shape="square",
        point_shading="flat",
    )
    segs = [
        (positions[f.a], positions[f.b]) for f in flags if f.a in positions and f.b in positions
    ]
    if segs:
        scene.add_line_segments("/coverage/spacing", np.array(segs), (230, 60, 160), thickness=0.03)


def landmark_rgb(lm: LandmarkState) -> RGB:
    """The colour `SiteScene` gives a landmark (for panels and tests)."""
    return landmark_color(lm.percent, reachable=lm.reachable, doubted=lm.doubted)
