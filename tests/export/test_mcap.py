"""`irloc export`: a simulated recording written as MCAP in both profiles and read back with
the `mcap` reader (protobuf decoding for the foxglove profile, the ROS 2 CDR decoder for the
ros2 profile): topics, schemas, counts, and values against the recording and the replay."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoder
from mcap_ros2.decoder import DecoderFactory as Ros2Decoder

from export.cli import main
from export.content import compose, export_content
from export.ros2_mcap import write_ros2
from export.topics import topics
from recording.reader import read_groundtruth, read_recording
from recording.replay_cli import main as replay
from recording.scoring import read_poses


def _read(path: Path) -> tuple[Any, dict[str, list[tuple[int, Any]]]]:
    """(summary, topic -> [(log time, decoded message)])."""
    out: dict[str, list[tuple[int, Any]]] = {}
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoder(), Ros2Decoder()])
        summary = reader.get_summary()
        for _, channel, message, decoded in reader.iter_decoded_messages():
            out.setdefault(channel.topic, []).append((message.log_time, decoded))
    return summary, out


def _yaw(q: Any) -> float:
    return 2 * math.atan2(q.z, q.w)


@pytest.fixture(scope="module")
def replayed(testbed_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("poses") / "poses.csv"
    assert replay([str(testbed_recording), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.parametrize("profile", ["foxglove", "ros2"])
def test_export_reads_back(
    profile: str,
    testbed_recording: Path,
    replayed: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "out.mcap"
    assert main([str(testbed_recording), "--mcap", str(out), "--profile", profile]) == 0
    assert f"wrote {out} ({profile})" in capsys.readouterr().out
    summary, msgs = _read(out)
    rec = read_recording(testbed_recording)
    frames = len(rec.frames)
    track = read_poses(replayed)
    posed = int(track.has_pose.sum())
    t_gt, gt = read_groundtruth(testbed_recording)

    schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert schemas == topics(profile)  # type: ignore[arg-type]
    encoding = {"foxglove": "protobuf", "ros2": "cdr"}[profile]
    assert {c.message_encoding for c in summary.channels.values()} == {encoding}
    counts = {t: len(m) for t, m in msgs.items()}
    assert counts["/cam0/image/compressed"] == frames
    assert counts["/cam0/camera_info"] == frames
    assert counts["/tf"] == frames and counts["/tf_static"] == 1
    assert counts["/irloc/pose"] == posed
    assert counts["/groundtruth"] == len(t_gt)
    assert counts["/landmarks"] == len(rec.leds)  # the start, then each LED change
    assert counts["/odom"] == int(np.sum(rec.odom_t_ns <= rec.frames[-1].t_ns))

    # the image is the recorded PNG as it is; the calibration is the lens
    _, first = msgs["/cam0/image/compressed"][0]
    assert first.format == {"foxglove": "png", "ros2": "mono8; png compressed"}[profile]
    assert bytes(first.data) == rec.frames[0].path.read_bytes()
    cal = msgs["/cam0/camera_info"][0][1]
    K = list(cal.K if profile == "foxglove" else cal.k)
    cam = rec.camera
    np.testing.assert_allclose(K, [cam.fu, 0, cam.cu, 0, cam.fv, cam.cv, 0, 0, 1])
    assert list(cal.D if profile == "foxglove" else cal.d) == list(cam.distortion)

    # poses: the replay's values, covariance in ROS's 6x6 layout
    rows = {int(t): k for k, t in enumerate(track.t_ns)}
    for t, m in msgs["/irloc/pose"][:: max(posed // 7, 1)]:
        k = rows[t]
        p = m.pose if profile == "foxglove" else m.pose.pose
        np.testing.assert_allclose(
            [p.position.x, p.position.y], track.pose[k, :2], rtol=0, atol=1e-6
        )
        assert abs(_yaw(p.orientation) - track.pose[k, 2]) < 1e-6
    cov_msgs = msgs["/irloc/pose_with_covariance" if profile == "foxglove" else "/irloc/pose"]
    t_last, last = cov_msgs[-1]
    cov = np.array(last.pose_covariance if profile == "foxglove" else last.pose.covariance)
    cov = cov.reshape(6, 6)
    np.testing.assert_allclose(
        np.diag(cov)[[0, 1, 5]], track.covariance_diag[rows[t_last]], rtol=2e-3
    )
    assert np.count_nonzero(cov[2:5, :]) == 0

    # REP-105: map -> odom composed with odom -> base_link is the pose
    for t, tf in msgs["/tf"][-3:]:
        parts = {}
        for x in tf.transforms:
            parent = x.parent_frame_id if profile == "foxglove" else x.header.frame_id
            tr = x.translation if profile == "foxglove" else x.transform.translation
            rot = x.rotation if profile == "foxglove" else x.transform.rotation
            parts[parent] = (tr.x, tr.y, _yaw(rot))
        pose = compose(parts["map"], parts["odom"])
        np.testing.assert_allclose(pose[:2], track.pose[rows[t], :2], atol=1e-6)  # CSV: 6 digits
        assert abs(pose[2] - track.pose[rows[t], 2]) < 1e-6

    # landmarks: every one dark at the start (leds.csv: none), lit once all are
    def colours(m: Any) -> list[tuple[float, float]]:
        if profile == "foxglove":
            return [(e.spheres[0].color.r, e.spheres[0].color.b) for e in m.entities]
        return [(mk.color.r, mk.color.b) for mk in m.markers if mk.ns == "landmarks"]

    dark, lit = msgs["/landmarks"][0][1], msgs["/landmarks"][-1][1]
    assert len(colours(dark)) == len(rec.landmark_map.ids)
    assert all(c == pytest.approx((0.35, 0.4)) for c in colours(dark))
    assert all(c == pytest.approx((1.0, 0.1)) for c in colours(lit))

    # annotations: spots and the IDs of the landmarks used, in the last frame with any
    t_used, used = [(t, k) for t, k in rows.items() if track.landmarks[k]][-1]
    ann = [m for t, m in msgs["/cam0/annotations"] if t == t_used]
    if profile == "foxglove":
        ids = sorted(int(x.text) for x in ann[0].texts)
        assert len(ann[0].circles) >= len(ids) * 2  # a spot circle and a landmark circle each
    else:
        ids = sorted(m.id for m in ann if m.ns == "landmarks")
        assert len(next(m for m in ann if m.ns == "spots").points) >= len(ids)
    assert ids == sorted(track.landmarks[used])

    # ground truth as recorded
    tg, g = msgs["/groundtruth"][-1]
    p = g.pose
    assert tg == t_gt[-1]
    np.testing.assert_allclose([p.position.x, p.position.y, _yaw(p.orientation)], gt[-1], atol=1e-9)


def test_ros2_profile_is_a_rosbag2(testbed_recording: Path, tmp_path: Path) -> None:
    """Without `.mcap` the ros2 profile writes the rosbag2 folder (metadata.yaml + MCAP)."""
    rec = read_recording(testbed_recording)
    short = dataclasses.replace(rec, frames=rec.frames[:12])
    out = tmp_path / "bag"
    counts = write_ros2(export_content(short), out)
    assert counts["/cam0/image/compressed"] == 12
    assert sorted(p.name for p in out.iterdir()) == ["bag.mcap", "metadata.yaml"]
    meta = (out / "metadata.yaml").read_text()
    assert "storage_identifier: mcap" in meta and "message_count: " in meta
    _, msgs = _read(out / "bag.mcap")
    assert len(msgs["/tf"]) == 12
    with (out / "bag.mcap").open("rb") as f:
        assert make_reader(f).get_header().profile == "ros2"


def test_bad_recording_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(tmp_path / "missing"), "--mcap", str(tmp_path / "x.mcap")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("irloc export: ") and "\n" not in err
    assert not (tmp_path / "x.mcap").exists()
