"""Calibration from uploaded bytes, as the server's multipart route calls it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration.uploads import calibrate_from_uploads, decode_images

DATA = Path(__file__).resolve().parents[1] / "data" / "chessboard"


def test_uploaded_photos_calibrate_like_files() -> None:
    files = [(p.name, p.read_bytes()) for p in sorted(DATA.glob("*.jpg"))]
    result = calibrate_from_uploads(files, pattern=(9, 6), square_m=0.025)
    assert [v.name for v in result.views] == [name for name, _ in files]
    np.testing.assert_allclose(result.camera.fu, 534.7, atol=1.0)
    data = json.loads(json.dumps(result.to_dict()))
    assert data["sensor"]["resolution"] == [640, 480]
    assert data["model"] == "pinhole"


def test_undecodable_files_are_named() -> None:
    good = (DATA / "left01.jpg").read_bytes()
    with pytest.raises(
        ValueError, match=r"2 files could not be decoded as an image: a.txt, empty.png"
    ):
        decode_images([("a.txt", b"hello"), ("ok.jpg", good), ("empty.png", b"")])
    with pytest.raises(ValueError, match="no files uploaded"):
        calibrate_from_uploads([])
    assert decode_images([("ok.jpg", good)])[0].shape == (480, 640)


def test_a_decompression_bomb_is_refused_from_its_header() -> None:
    import resource
    import time

    from tests.calibration.bombs import png_bomb

    bomb = png_bomb(20000, 20000)
    good = (DATA / "left01.jpg").read_bytes()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"huge.png: 400 MP is more than 40 MP") as exc:
        decode_images([("ok.jpg", good), ("huge.png", bomb)])
    elapsed = time.perf_counter() - t0
    assert elapsed < 0.2, elapsed
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0 < 50_000  # < 50 MB
    assert "MAX" not in str(exc.value)
    # a photo whose header says one thing is not decoded as another
    with pytest.raises(ValueError, match="could not be decoded"):
        decode_images([("fake.png", b"\x89PNG\r\n\x1a\n" + b"\0" * 40)])
