"""An independent recording generator: EuRoC folders written without any of irloc's code.

The robustness matrix (`bench/robustness.py`) runs on recordings of our own simulator
(`sim/`), so whatever that simulator leaves out, the matrix cannot see. This generator
shares nothing with it: its own kinematics, its own odometry error model, OpenCV's
projection (`cv2.projectPoints`, `cv2.fisheye.projectPoints`), its own spot rendering
(saturating LED cores with a halo, motion blur over the exposure, a vignetted background,
shot and read noise) and its own CSV writing, straight from the recording contract
(/work/shared/contracts/recording.md, docs/recording.md). It imports numpy, OpenCV and
yaml only: a check that the localizer works on data it was never shaped by.

    python bench/foreign/generate.py CASE OUTDIR [--seconds S] [--seed N]

CASE is one of `CASES` (bench/foreign/cases.py).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import yaml

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from bench.foreign.cases import CASES, Case

FloatArray = npt.NDArray[np.float64]
NS = 1_000_000_000


@dataclass(frozen=True)
class Lens:
    """A camera as OpenCV models it: K, distortion, the model, the image size."""

    K: FloatArray
    dist: FloatArray
    fisheye: bool
    size: tuple[int, int]  # width, height

    def project(self, p_cam: FloatArray) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Pixels of camera-frame points (N, 3) and which are in front and inside."""
        front = p_cam[:, 2] > 0.05
        if not front.any():
            return np.zeros((len(p_cam), 2)), front
        pts = p_cam[front].reshape(-1, 1, 3)
        zero = np.zeros(3)
        if self.fisheye:
            # the equidistant model stays monotonic to 90 deg; beyond ~80 deg it is not used
            ang = np.arccos(np.clip(p_cam[front, 2] / np.linalg.norm(p_cam[front], axis=1), -1, 1))
            px, _ = cv2.fisheye.projectPoints(pts, zero, zero, self.K, self.dist)
            ok_model = ang < math.radians(80)
        else:
            px, _ = cv2.projectPoints(pts, zero, zero, self.K, self.dist)
            # the polynomial folds back outside its fitted field: keep rays within 65 deg
            ang = np.arccos(np.clip(p_cam[front, 2] / np.linalg.norm(p_cam[front], axis=1), -1, 1))
            ok_model = ang < math.radians(65)
        out = np.zeros((len(p_cam), 2))
        out[front] = px.reshape(-1, 2)
        w, h = self.size
        inside = front.copy()
        inside[front] = (
            ok_model
            & (out[front, 0] >= 2)
            & (out[front, 0] <= w - 3)
            & (out[front, 1] >= 2)
            & (out[front, 1] <= h - 3)
        )
        return out, inside


def rot_z(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def rot_x(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def body_from_camera(case: Case) -> FloatArray:
    """T_BS: the camera looks up, turned by the mounting yaw, tilted, offset from the axle."""
    # looking up: the optical axis (camera z) along the body's +z, image x along the body's
    # x (any right-handed frame with z up is a valid upward camera; T_BS says which)
    R_up = np.eye(3)
    R = (
        rot_z(case.mount_yaw_rad)
        @ rot_x(case.mount_tilt_rad[0])
        @ rot_y(case.mount_tilt_rad[1])
        @ R_up
    )
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [case.mount_offset_m[0], case.mount_offset_m[1], case.mount_height_m]
    return T


def in_camera(pose: FloatArray, T_BS: FloatArray, p_world: FloatArray) -> FloatArray:
    """World points (N, 3) in the camera frame of a robot at planar `pose` (x, y, theta)."""
    T_WB = np.eye(4)
    T_WB[:3, :3] = rot_z(float(pose[2]))
    T_WB[:3, 3] = [pose[0], pose[1], 0.0]
    T_CW = np.linalg.inv(T_WB @ T_BS)
    return p_world @ T_CW[:3, :3].T + T_CW[:3, 3]


@dataclass
class Motion:
    """The true planar path, sampled at 1 kHz from the case's command segments."""

    t: FloatArray  # s
    pose: FloatArray  # (N, 3)
    wheels: FloatArray  # (N, 2) true v_left, v_right


def drive(case: Case, seconds: float, start_s: float) -> Motion:
    """Integrate the commanded (v, w) with first-order lag (the drive's response)."""
    dt = 1e-3
    n = int(seconds / dt) + 1
    t = np.arange(n) * dt
    pose = np.zeros((n, 3))
    wheels = np.zeros((n, 2))
    pose[0] = case.start
    v = w = 0.0
    seg_t = np.cumsum([0.0] + [s[0] for s in case.segments])
    tau = case.drive_lag_s
    for k in range(1, n):
        tk = t[k] - start_s
        if tk < 0:
            cmd_v = cmd_w = 0.0
        else:
            j = int(np.searchsorted(seg_t, tk % seg_t[-1], side="right")) - 1
            _, cmd_v, cmd_w = case.segments[min(j, len(case.segments) - 1)]
        a = dt / tau if tau > 0 else 1.0
        v += (cmd_v - v) * min(a, 1.0)
        w += (cmd_w - w) * min(a, 1.0)
        x, y, th = pose[k - 1]
        if case.kidnap_s is not None and t[k - 1] < case.kidnap_s <= t[k]:
            x, y, th = case.kidnap_to  # lifted and set down: nothing of it in the odometry
        if case.stall_s is not None and case.stall_s[0] <= t[k] < case.stall_s[1]:
            pose[k] = (x, y, th)  # against an obstacle: the wheels spin, the robot stays
        else:
            pose[k] = (
                x + v * dt * math.cos(th + 0.5 * w * dt),
                y + v * dt * math.sin(th + 0.5 * w * dt),
                th + w * dt,
            )
        half = 0.5 * case.wheel_base_m * w
        wheels[k] = (v - half, v + half)
    pose[:, 2] = (pose[:, 2] + math.pi) % (2 * math.pi) - math.pi
    pose[pose[:, 2] == -math.pi, 2] = math.pi
    return Motion(t, pose, wheels)


def wheel_spin(case: Case, motion: Motion) -> FloatArray:
    """(N, 2) factors by which each wheel turns faster than the floor moves under it: 1
    except where the axle's midpoint is inside one of `case.slip_zones` (a wet patch)."""
    spin = np.ones((len(motion.t), 2))
    for x0, y0, x1, y1, f_left, f_right in case.slip_zones:
        inside = (
            (motion.pose[:, 0] >= x0)
            & (motion.pose[:, 0] <= x1)
            & (motion.pose[:, 1] >= y0)
            & (motion.pose[:, 1] <= y1)
        )
        spin[inside] = (f_left, f_right)
    return spin


def odometry_stamps(case: Case, t_sample: FloatArray, rng: np.random.Generator) -> list[int]:
    """The stamps (ns from the epoch) of odometry samples taken at `t_sample` (s): each one
    late by a random `odom_jitter_s`; with `odom_burst` > 1 the samples reach the host (and
    are stamped) that many at a time, 1 ms apart, when the last of them is taken (a USB or
    CAN bridge that buffers). Strictly increasing, as a driver would write them."""
    t = t_sample.copy()
    if case.odom_burst > 1:
        n = case.odom_burst
        for i in range(len(t)):
            last = min((i // n + 1) * n - 1, len(t) - 1)
            t[i] = t_sample[last] + 1e-3 * (i - (i // n) * n)
    if case.odom_jitter_s > 0:
        t = t + rng.uniform(0.0, case.odom_jitter_s, len(t))
    ns = [round(v * NS) for v in t]
    for i in range(1, len(ns)):
        ns[i] = max(ns[i], ns[i - 1] + 1000)
    return ns


@functools.cache
def _vignetted_background_cached(w: int, h: int, level: float) -> FloatArray:
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (0.25 * (w * w + h * h))
    return level * (1.0 - 0.4 * r2)


def _vignetted_background(w: int, h: int, level: float) -> FloatArray:
    """The dark level, 40 % lower in the corners (a fresh copy)."""
    return _vignetted_background_cached(w, h, level).copy()


def render(
    lens: Lens,
    px_samples: list[FloatArray],
    ok: npt.NDArray[np.bool_],
    brightness: FloatArray,
    case: Case,
    rng: np.random.Generator,
    stray: list[tuple[FloatArray, float, float]],
) -> npt.NDArray[np.uint8]:
    """One 8-bit frame: each lit LED a saturating Gaussian core plus a wide halo, smeared over
    the exposure's sub-samples; `stray` lights that are no landmark (camera-frame centre, radius
    m, counts); a vignetted background; shot and read noise."""
    w, h = lens.size
    yy, xx = np.mgrid[0:h, 0:w]
    img = _vignetted_background(w, h, case.background)
    s_core, s_halo = case.spot_sigma_px, 3.0 * case.spot_sigma_px
    m = len(px_samples)
    for i in np.flatnonzero(ok):
        amp = case.spot_peak * brightness[i]
        cx = [float(p[i, 0]) for p in px_samples]
        cy = [float(p[i, 1]) for p in px_samples]
        r = int(4 * s_halo + abs(cx[-1] - cx[0]) + abs(cy[-1] - cy[0])) + 2
        x0, x1 = max(int(min(cx)) - r, 0), min(int(max(cx)) + r + 1, w)
        y0, y1 = max(int(min(cy)) - r, 0), min(int(max(cy)) + r + 1, h)
        if x0 >= x1 or y0 >= y1:
            continue
        gx, gy = xx[y0:y1, x0:x1], yy[y0:y1, x0:x1]
        patch = np.zeros(gx.shape)
        for u, v in zip(cx, cy, strict=True):
            d2 = (gx - u) ** 2 + (gy - v) ** 2
            patch += np.exp(-0.5 * d2 / s_core**2) + 0.08 * np.exp(-0.5 * d2 / s_halo**2)
        img[y0:y1, x0:x1] += amp * patch / m
    for p_cam, radius_m, amp in stray:  # lamps and sunlit patches: flat disks, soft edges
        px, inside = lens.project(p_cam[None, :])
        if not inside[0]:
            continue
        r_px = max(radius_m / float(p_cam[2]) * float(lens.K[0, 0]), 1.5)
        d = np.sqrt((xx - px[0, 0]) ** 2 + (yy - px[0, 1]) ** 2)
        img += amp * np.clip(1.2 - d / r_px, 0.0, 1.0)
    for gx_, gy_, amp in case.glints:
        d2 = (xx - gx_ * w) ** 2 + (yy - gy_ * h) ** 2
        img += amp * np.exp(-0.5 * d2 / 2.0**2)
    img = rng.poisson(np.clip(img, 0, None) / case.gain) * case.gain
    img = img + rng.normal(0.0, case.read_noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def generate(case: Case, out: Path, seconds: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    w, h = case.size
    K = np.array(
        [
            [case.f_px, 0, w / 2 - 0.5 + case.c_off[0]],
            [0, case.f_px * case.aspect, h / 2 - 0.5 + case.c_off[1]],
            [0, 0, 1.0],
        ]
    )
    dist = np.array(case.dist, dtype=np.float64)
    true_lens = Lens(K, dist, case.fisheye, case.size)
    # the calibration handed over: what Zhang's method leaves (focal 0.2 %, centre 0.6 px,
    # each distortion coefficient 5 %)
    e = case.calib_error
    K_cal = K.copy()
    K_cal[0, 0] *= 1 + e * rng.normal(0, 0.002)
    K_cal[1, 1] *= 1 + e * rng.normal(0, 0.002)
    K_cal[0, 2] += e * rng.normal(0, 0.6)
    K_cal[1, 2] += e * rng.normal(0, 0.6)
    dist_cal = dist * (1 + e * rng.normal(0, 0.05, dist.shape))
    # landmarks and their surveyed map
    p_true = case.layout(rng)
    ids = np.arange(case.first_id, case.first_id + len(p_true))
    p_map = p_true + rng.normal(0, case.survey_sigma_m, p_true.shape)
    T_BS = body_from_camera(case)
    sweep_s = 0.2 + 3 * 8 / case.rate_hz + 0.6
    motion = drive(case, seconds, start_s=sweep_s)

    out.mkdir(parents=True, exist_ok=True)
    (out / "cam0" / "data").mkdir(parents=True, exist_ok=True)
    (out / "odom0").mkdir(parents=True, exist_ok=True)
    (out / "map.json").write_text(
        json.dumps(
            {
                "landmarks": [
                    {"id": int(i), "x": float(p[0]), "y": float(p[1]), "z": float(p[2])}
                    for i, p in zip(ids, p_map, strict=True)
                ]
            },
            indent=1,
        )
    )
    (out / "robot.yaml").write_text(
        yaml.safe_dump({"wheel_base": case.wheel_base_m, "max_speed": case.max_speed})
    )
    model = "equidistant" if case.fisheye else "radial-tangential"
    sensor = {
        "sensor_type": "camera",
        "comment": "bench/foreign/generate.py (independent of irloc's sim)",
        "T_BS": {"cols": 4, "rows": 4, "data": [float(v) for v in T_BS.reshape(-1)]},
        "rate_hz": case.rate_hz,
        "resolution": [w, h],
        "camera_model": "pinhole",
        "intrinsics": [
            float(K_cal[0, 0]),
            float(K_cal[1, 1]),
            float(K_cal[0, 2]),
            float(K_cal[1, 2]),
        ],
        "distortion_model": model,
        "distortion_coefficients": [float(v) for v in dist_cal],
    }
    (out / "cam0" / "sensor.yaml").write_text(yaml.safe_dump(sensor, sort_keys=False))

    # odometry: wheel radii and wheel base off by a little, noise per sample, at its own rate
    scale = 1 + np.array(case.wheel_scale_error)
    spin = wheel_spin(case, motion)
    odo_lines = ["#timestamp [ns],v_left [m/s],v_right [m/s]"]
    step = round(1.0 / case.odom_hz / 1e-3)
    stamps = odometry_stamps(case, motion.t[step::step], rng)
    for k, t_stamp in zip(range(step, len(motion.t), step), stamps, strict=True):
        mean = (motion.wheels[k - step + 1 : k + 1] * spin[k - step + 1 : k + 1]).mean(axis=0)
        meas = mean / scale + rng.normal(0, case.odom_noise, 2) * np.maximum(np.abs(mean), 0.02)
        odo_lines.append(f"{case.epoch_ns + t_stamp},{meas[0]:.6f},{meas[1]:.6f}")
    (out / "odom0" / "data.csv").write_text("\n".join(odo_lines) + "\n")

    # LEDs: dark, then the nearest landmarks one at a time, then all (the start-up sweep)
    near = np.argsort(np.hypot(p_map[:, 0] - case.start[0], p_map[:, 1] - case.start[1]))[:8]
    frame_dt = 1.0 / case.rate_hz
    led_lines = ["#timestamp [ns],on", f"{case.epoch_ns},none"]
    lit_state: list[tuple[float, set[int] | None]] = [(0.0, set())]
    t_led = 0.2
    for j in near:
        led_lines.append(f"{case.epoch_ns + round(t_led * NS)},{int(ids[j])}")
        lit_state.append((t_led, {int(ids[j])}))
        t_led += 3 * frame_dt
    led_lines.append(f"{case.epoch_ns + round(t_led * NS)},all")
    lit_state.append((t_led, None))
    (out / "leds.csv").write_text("\n".join(led_lines) + "\n")

    frames = ["#timestamp [ns],filename"]
    truth = ["timestamp_ns,x,y,theta"]
    n_sub = 5
    t_frame = frame_dt * 0.5
    while t_frame < seconds - case.exposure_s - case.camera_lag_s:
        # the camera's clock runs `camera_lag_s` behind the exposure's mid-point (a stamp
        # taken on arrival, or an unsynchronised clock); the truth is the pose at the stamp
        t_ns = case.epoch_ns + round((t_frame + case.camera_lag_s) * NS)
        state = [s for t0, s in lit_state if t0 <= t_frame][-1]
        lit = np.ones(len(ids), bool) if state is None else np.isin(ids, list(state))
        samples, ok = [], np.ones(len(ids), bool)
        for dt in np.linspace(-0.5, 0.5, n_sub) * case.exposure_s:
            k = min(round((t_frame + dt) / 1e-3), len(motion.t) - 1)
            px, inside = true_lens.project(in_camera(motion.pose[k], T_BS, p_true))
            samples.append(px)
            ok &= inside
        k_stamp = min(round((t_frame + case.camera_lag_s) / 1e-3), len(motion.t) - 1)
        x, y, th = motion.pose[k_stamp]
        k = min(round(t_frame / 1e-3), len(motion.t) - 1)
        p_cam = in_camera(motion.pose[k], T_BS, p_true)
        dist_m = np.linalg.norm(p_cam, axis=1)
        cos_a = np.clip(p_cam[:, 2] / dist_m, 0, 1)
        bright = (2.5 / dist_m) ** 2 * cos_a**3 * case.led_power[ids - case.first_id]
        stray = [
            (in_camera(motion.pose[k], T_BS, np.array([[sx, sy, sz]]))[0], r, a)
            for sx, sy, sz, r, a in case.stray_lights
        ]
        image = render(true_lens, samples, ok & lit, bright, case, rng, stray)
        if rng.random() >= case.drop_frames:
            cv2.imwrite(str(out / "cam0" / "data" / f"{t_ns}.png"), image)
            frames.append(f"{t_ns},{t_ns}.png")
            truth.append(f"{t_ns},{x:.6f},{y:.6f},{th:.7f}")
        t_frame += frame_dt
    (out / "cam0" / "data.csv").write_text("\n".join(frames) + "\n")
    (out / "groundtruth.csv").write_text("\n".join(truth) + "\n")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case", choices=sorted(CASES))
    p.add_argument("out", type=Path)
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args(argv)
    case = CASES[a.case]
    generate(case, a.out, a.seconds or case.seconds, a.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
