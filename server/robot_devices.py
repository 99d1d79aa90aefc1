"""What a robot's configuration may open on the server: checked before it is saved.

- `device` (the camera): a camera index (`0`), a video device (a character device such as
  `/dev/video0`), or a video file inside the data folder or a folder of `device_dirs`;
  a URL (`http://`, `rtsp://`...) only with `allow_network_devices`.
- `wheel_port`: a serial device (a character device, `/dev/ttyUSB0`, a symlink to one);
  a pyserial URL (`socket://`, `rfc2217://`) only with `allow_network_devices`.
- With the live site running, a camera that cannot be opened is refused (422) instead of
  being saved and failing in the log.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from live.settings import Settings
from store.models import RobotCreate


def _is_char_device(path: Path) -> bool:
    try:
        return stat.S_ISCHR(os.stat(path).st_mode)
    except OSError:
        return False


def _inside(path: Path, folders: list[Path]) -> bool:
    real = path.resolve()
    return any(real.is_relative_to(f.resolve()) for f in folders)


def check_camera_device(device: str, settings: Settings) -> None:
    """ValueError naming what is wrong with `device` (see the module)."""
    if device.isdigit():
        return
    if "://" in device:
        if settings.allow_network_devices:
            return
        raise ValueError(
            f"device: {device!r} is a URL: network cameras need the setting allow_network_devices"
        )
    path = Path(device)
    if _is_char_device(path):
        return
    folders = [settings.data_dir, *settings.device_dirs]
    if not path.is_absolute() or not _inside(path, folders):
        shown = ", ".join(str(f) for f in folders)
        raise ValueError(
            f"device: {device!r} is not a camera index, a video device or a video file in "
            f"{shown} (setting device_dirs)"
        )
    if not path.is_file():
        raise ValueError(f"device: {device!r}: no such video file")


def check_wheel_port(port: str, settings: Settings) -> None:
    """ValueError naming what is wrong with `port` (see the module)."""
    if "://" in port:
        if settings.allow_network_devices:
            return
        raise ValueError(
            f"wheel_port: {port!r} is a network URL: it needs the setting allow_network_devices"
        )
    if not _is_char_device(Path(port)):
        raise ValueError(f"wheel_port: {port!r} is not a serial device")


def camera_opens(device: str) -> bool:
    """Whether OpenCV can open `device` now (and read its first frame)."""
    import cv2

    cap = cv2.VideoCapture(int(device) if device.isdigit() else device)
    try:
        return bool(cap.isOpened()) and bool(cap.read()[0])
    finally:
        cap.release()


def check_devices(robot: RobotCreate, settings: Settings) -> None:
    """ValueError (422) when the configuration names something it may not open, or, with the
    live site running, a camera that does not open."""
    if robot.device:
        check_camera_device(robot.device, settings)
    if robot.wheel_port:
        check_wheel_port(robot.wheel_port, settings)
    live = robot.source == "camera" and settings.site_enabled
    if live and robot.device and not camera_opens(robot.device):
        raise ValueError(f"device: camera {robot.device!r} cannot be opened")
