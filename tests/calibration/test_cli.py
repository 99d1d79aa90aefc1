"""`irloc calibrate` end to end on OpenCV's sample photos, and its refusals."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from calibration.board import BoardSpec
from calibration.cli import main
from irloc.cli import main as irloc_main
from localizer.camera import T_body_camera_upward, camera_from_sensor, sensor_from_camera

DATA = Path(__file__).resolve().parents[1] / "data" / "chessboard"


def test_writes_sensor_yaml_and_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cam0" / "sensor.yaml"
    report = tmp_path / "report.json"
    code = irloc_main(
        ["calibrate", str(DATA), "--pattern", "9x6", "--square", "0.025", "--out", str(out),
         "--report", str(report)]
    )  # fmt: skip
    assert code == 0
    cam = camera_from_sensor(yaml.safe_load(out.read_text()))
    np.testing.assert_allclose([cam.fu, cam.fv], [534.7, 534.7], atol=1.0)
    assert cam.resolution == (640, 480) and cam.distortion_model == "radial-tangential"
    np.testing.assert_allclose(cam.T_body_camera, T_body_camera_upward())
    data = json.loads(report.read_text())
    assert data["used_views"] == 13 and len(data["views"]) == 13
    text = capsys.readouterr().out
    assert "left13.jpg" in text and "views used: 13 of 13" in text and "wrote" in text
    assert out.read_text().startswith("# irloc calibrate: pinhole lens, RMS 0.3")


def test_keeps_the_mounting_of_an_existing_sensor_yaml(tmp_path: Path) -> None:
    old = sensor_from_camera(camera_from_sensor(yaml.safe_load(_sensor_text())))
    T = T_body_camera_upward(yaw=0.5, offset_xy=(0.1, -0.02))
    old["T_BS"]["data"] = T.reshape(-1).tolist()
    old["rate_hz"] = 15.0
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(old))
    out = tmp_path / "new.yaml"
    photos = [str(p) for p in sorted(DATA.glob("*.jpg"))[:8]]
    assert main([*photos, "--mounting", str(tmp_path / "old.yaml"), "--out", str(out)]) == 0
    cam = camera_from_sensor(yaml.safe_load(out.read_text()))
    np.testing.assert_allclose(cam.T_body_camera, T)
    assert cam.rate_hz == 15.0


def _sensor_text() -> str:
    return (
        "camera_model: pinhole\nintrinsics: [500, 500, 320, 240]\nresolution: [640, 480]\n"
        "distortion_model: radial-tangential\ndistortion_coefficients: [0, 0, 0, 0]\n"
    )


def _fails(argv: list[str], out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    code = main([*argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert code != 0
    assert not out.exists()
    assert list(out.parent.iterdir()) == [] or all(
        p.suffix != ".yaml" for p in out.parent.iterdir()
    )
    return err


def test_images_without_a_board(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for i in range(5):
        cv2.imwrite(str(tmp_path / f"wall{i}.png"), np.full((480, 640), 90 + i, np.uint8))
    err = _fails([str(tmp_path)], tmp_path / "sensor.yaml", capsys)
    assert err.startswith("irloc calibrate: error: no chessboard with 9x6 inner corners")
    assert err.count("\n") == 1  # one line, no traceback


def test_mixed_resolutions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    photos = sorted(DATA.glob("*.jpg"))[:6]
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), cv2.resize(cv2.imread(str(photos[0])), (320, 240)))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    err = _fails([*map(str, photos), str(small)], out_dir / "sensor.yaml", capsys)
    assert "mixed image resolutions" in err and "small.png" in err


def test_too_few_views(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    photos = sorted(DATA.glob("*.jpg"))[:3]
    err = _fails([*map(str, photos)], tmp_path / "sensor.yaml", capsys)
    assert "only 3 of 3 images show the board; need at least 5 views" in err


def test_wrong_pattern(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    photos = sorted(DATA.glob("*.jpg"))[:2]
    err = _fails([*map(str, photos), "--pattern", "10x7"], tmp_path / "sensor.yaml", capsys)
    assert "try --pattern 9x6" in err


def test_bad_arguments_and_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sensor.yaml"
    assert main([str(DATA), "--pattern", "nine", "--out", str(out)]) == 2
    assert "COLSxROWS" in capsys.readouterr().err
    err = _fails([str(tmp_path / "missing.jpg")], out, capsys)
    assert "missing.jpg: no such file or folder" in err
    broken = tmp_path / "broken.jpg"
    broken.write_bytes(b"not a jpeg")
    shutil.copy(DATA / "left01.jpg", tmp_path / "left01.jpg")
    err = _fails([str(broken), str(tmp_path / "left01.jpg")], out, capsys)
    assert "1 file could not be decoded as an image:" in err and "broken.jpg" in err
    assert not out.exists()


def test_charuco_fisheye_from_the_command_line(tmp_path: Path) -> None:
    from tests.calibration.test_lens_synthetic import PIXELS, _photos, _true_camera

    camera = _true_camera("fisheye")
    board = BoardSpec((9, 6), 0.03, kind="charuco", marker_m=0.0225, dictionary="DICT_4X4_100")
    photos = _photos(camera, board, PIXELS[:8], seed=5, distance_m=0.4, px_per_square=48)
    for k, img in enumerate(photos):
        cv2.imwrite(str(tmp_path / f"board{k:02d}.png"), img)
    out = tmp_path / "sensor.yaml"
    argv = [str(tmp_path), "--pattern", "9x6", "--square", "0.03", "--charuco", "DICT_4X4_100",
            "--marker", "0.0225", "--model", "fisheye", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    got = camera_from_sensor(yaml.safe_load(out.read_text()))
    assert got.distortion_model == "equidistant"
    np.testing.assert_allclose([got.fu, got.fv], [camera.fu, camera.fv], rtol=0.005)
    np.testing.assert_allclose([got.cu, got.cv], [camera.cu, camera.cv], atol=1.0)
