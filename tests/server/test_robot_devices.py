"""A robot's configuration opens only local devices: no URL, no file outside the data
folder, no regular file as a serial port; a camera that cannot be opened is refused."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from live.settings import Settings
from localizer.camera import sensor_from_camera
from server.robot_devices import check_camera_device, check_devices, check_wheel_port
from sim.cameras import wide_angle_camera
from store.models import RobotCreate
from tests.server.conftest import Api


def settings(tmp_path: Path, **kw: object) -> Settings:
    return Settings(data_dir=tmp_path, site_enabled=False, **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("device", "said"),
    [
        ("http://169.254.169.254/latest", "is a URL"),
        ("/etc/shadow", "not a camera index"),
        ("../../etc/passwd", "not a camera index"),
    ],
)
def test_a_camera_may_not_be_a_url_or_a_file_elsewhere(
    tmp_path: Path, device: str, said: str
) -> None:
    with pytest.raises(ValueError, match=said):
        check_camera_device(device, settings(tmp_path))


def test_a_camera_may_be_an_index_a_video_device_or_a_video_file_in_the_data_folder(
    tmp_path: Path,
) -> None:
    video = tmp_path / "drive.mp4"
    video.write_bytes(b"\0")
    for ok in ("0", "/dev/null", str(video)):  # /dev/null: a character device
        check_camera_device(ok, settings(tmp_path))
    check_camera_device("rtsp://cam", settings(tmp_path, allow_network_devices=True))


def test_a_wheel_port_must_be_a_serial_device(tmp_path: Path) -> None:
    for bad, said in (("socket://10.0.0.1:23", "network URL"), ("/etc/shadow", "not a serial")):
        with pytest.raises(ValueError, match=said):
            check_wheel_port(bad, settings(tmp_path))
    master, slave = os.openpty()
    try:
        check_wheel_port(os.ttyname(slave), settings(tmp_path))
    finally:
        os.close(master)
        os.close(slave)


def test_with_the_site_running_a_camera_that_does_not_open_is_refused(tmp_path: Path) -> None:
    video = tmp_path / "broken.mp4"
    video.write_bytes(b"not a video")
    robot = RobotCreate(name="cam1", source="camera", device=str(video), wheel_base=0.4)
    with pytest.raises(ValueError, match="cannot be opened"):
        check_devices(robot, Settings(data_dir=tmp_path, site_enabled=True))


def test_the_api_answers_422_naming_the_device(api: Api) -> None:
    camera = sensor_from_camera(wide_angle_camera("fisheye"))
    body = {"name": "cam9", "source": "camera", "device": "/etc/shadow", "wheel_base": 0.4,
            "camera": camera}  # fmt: skip
    r = api.client.put("/api/v1/robots/cam9/config", json=body, headers=api.h("admin"))
    assert r.status_code == 422 and "/etc/shadow" in r.json()["detail"]
    r = api.client.get("/api/v1/robots/cam9/config", headers=api.h("viewer"))
    assert r.status_code == 404  # nothing saved
