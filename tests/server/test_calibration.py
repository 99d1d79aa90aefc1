"""`POST /robots/{name}/calibration/lens`: multipart upload of real chessboard photos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from localizer.camera import (
    CameraModel,
    T_body_camera_upward,
    camera_from_sensor,
    sensor_from_camera,
)
from tests.server.conftest import Api

PHOTOS = Path(__file__).parents[1] / "data" / "chessboard"
URL = "/api/v1/robots/cam1/calibration/lens"


def _robot(api: Api) -> dict[str, object]:
    mount = T_body_camera_upward(yaw=np.pi / 2, offset_xy=(0.1, 0.0), height=0.4)
    cam = CameraModel(640, 480, 500.0, 500.0, 320.0, 240.0, "radial-tangential", np.zeros(5), mount)
    body = {
        "name": "cam1",
        "source": "camera",
        "device": "0",
        "wheel_base": 0.36,
        "camera": sensor_from_camera(cam),
    }
    r = api.client.put("/api/v1/robots/cam1/config", json=body, headers=api.h("admin"))
    assert r.status_code == 200, r.text
    return body


def _files(names: list[str]) -> list[tuple[str, tuple[str, bytes, str]]]:
    return [("files", (n, (PHOTOS / n).read_bytes(), "image/jpeg")) for n in names]


@pytest.mark.slow
def test_upload_calibrates_and_stores_keeping_the_mounting(api: Api) -> None:
    before = _robot(api)
    names = sorted(p.name for p in PHOTOS.glob("*.jpg"))[:8]
    r = api.client.post(
        URL,
        files=_files(names),
        data={"pattern": "9x6", "square_m": "0.025"},
        headers=api.h("operator"),
    )
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["stored"] is True
    assert 0.1 < out["rms_px"] < 1.0
    stored = api.client.get("/api/v1/robots/cam1/config", headers=api.h("viewer")).json()
    cam = camera_from_sensor(stored["camera"])
    np.testing.assert_allclose([cam.fu, cam.fv], out["sensor"]["intrinsics"][:2])
    assert 400 < cam.fu < 700  # OpenCV's sample camera, ~536 px
    old = camera_from_sensor(before["camera"])  # type: ignore[arg-type]
    np.testing.assert_allclose(cam.T_body_camera, old.T_body_camera)


def test_bad_upload_is_422_naming_the_file_and_stores_nothing(api: Api) -> None:
    before = _robot(api)
    files = [("files", ("notes.txt", b"not an image", "text/plain"))]
    r = api.client.post(URL, files=files, headers=api.h("operator"))
    assert r.status_code == 422
    assert "notes.txt" in r.json()["detail"]
    stored = api.client.get("/api/v1/robots/cam1/config", headers=api.h("viewer")).json()
    assert stored["camera"]["intrinsics"] == before["camera"]["intrinsics"]  # type: ignore[index]


def test_wrong_pattern_is_422(api: Api) -> None:
    _robot(api)
    r = api.client.post(
        URL,
        files=_files(["left01.jpg", "left02.jpg", "left03.jpg"]),
        data={"pattern": "7x7", "min_views": "3"},
        headers=api.h("operator"),
    )
    assert r.status_code == 422
    assert "pattern" in r.json()["detail"]


def test_viewer_may_not_calibrate(api: Api) -> None:
    _robot(api)
    r = api.client.post(URL, files=_files(["left01.jpg"]), headers=api.h("viewer"))
    assert r.status_code == 403
