"""The floor plan through the API: upload, placement by two points, bad files refused."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from store.floorplan import Placement
from tests.server.conftest import Api


def _png(w: int = 200, h: int = 100) -> bytes:
    img = np.full((h, w, 3), 255, np.uint8)
    cv2.rectangle(img, (10, 10), (w - 10, h - 10), (0, 0, 0), 2)
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return buf.tobytes()


def _query(a_px: tuple[float, float], a_m: tuple[float, float], b_px: tuple[float, float],
           b_m: tuple[float, float]) -> str:  # fmt: skip
    parts = [f"{k}={v}" for k, pt in (("a_px", a_px), ("a_m", a_m), ("b_px", b_px),
                                        ("b_m", b_m)) for v in pt]  # fmt: skip
    return "&".join(parts)


def test_upload_place_and_read_back(api: Api) -> None:
    c, h = api.client, api.h("admin")
    assert c.get("/api/v1/map/floorplan", headers=h).status_code == 404
    q = _query((0, 0), (0, 10), (200, 0), (10, 10))  # top edge along +x, 5 cm a pixel
    r = c.put(f"/api/v1/map/floorplan?{q}", content=_png(),
              headers={**h, "Content-Type": "image/png"})  # fmt: skip
    assert r.status_code == 200, r.text
    info = r.json()
    assert (info["width_px"], info["height_px"]) == (200, 100)
    assert info["metres_per_px"] == pytest.approx(0.05)
    assert info["rotation_rad"] == pytest.approx(0.0)
    np.testing.assert_allclose(info["center_m"], [5.0, 7.5])  # rows run toward -y
    assert (info["width_m"], info["height_m"]) == pytest.approx((10.0, 5.0))
    got = c.get("/api/v1/map/floorplan", headers=api.h("viewer"))
    assert got.status_code == 200 and got.content == _png()
    assert got.headers["content-type"] == "image/png"
    # moved: the image's top edge now runs north from the origin
    body = {"a_px": [0, 0], "a_m": [0, 0], "b_px": [100, 0], "b_m": [0, 5]}
    r = c.patch("/api/v1/map/floorplan/placement", json=body, headers=h)
    assert r.json()["rotation_rad"] == pytest.approx(math.pi / 2)
    assert c.get("/api/v1/map/floorplan/placement", headers=h).json()["width_m"] == 10.0
    assert c.delete("/api/v1/map/floorplan", headers=h).status_code == 204
    assert c.get("/api/v1/map/floorplan/placement", headers=h).status_code == 404


def test_bad_files_and_placements_are_refused_naming_the_problem(api: Api) -> None:
    c, h = api.client, api.h("admin")
    q = _query((0, 0), (0, 0), (100, 0), (5, 0))
    cases = [
        ("image/gif", _png(), "not image/png or image/jpeg"),
        ("image/jpeg", _png(), "not a image/jpeg image"),
        ("image/png", b"\x89PNG\r\n\x1a\n" + b"junk" * 10, "cannot be decoded"),
    ]
    for ctype, data, msg in cases:
        r = c.put(f"/api/v1/map/floorplan?{q}", content=data, headers={**h, "Content-Type": ctype})
        assert r.status_code == 422 and msg in r.json()["detail"], (ctype, r.text)
    same = _query((0, 0), (0, 0), (0, 0), (5, 0))
    r = c.put(f"/api/v1/map/floorplan?{same}", content=_png(),
              headers={**h, "Content-Type": "image/png"})  # fmt: skip
    assert r.status_code == 422 and "less than 1 px apart" in r.json()["detail"]
    r = c.put(f"/api/v1/map/floorplan?{q}", content=_png(),
              headers={**api.h("operator"), "Content-Type": "image/png"})  # fmt: skip
    assert r.status_code == 403
    assert c.get("/api/v1/map/floorplan", headers=h).status_code == 404  # nothing stored


def test_two_points_fix_scale_rotation_and_shift() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        scale, rot = rng.uniform(0.01, 0.2), rng.uniform(-math.pi, math.pi)
        shift = rng.uniform(-20, 20, 2)
        c, s = math.cos(rot), math.sin(rot)

        def floor(u: float, v: float) -> tuple[float, float]:
            p = scale * np.array([[c, -s], [s, c]]) @ np.array([u, -v]) + shift  # noqa: B023
            return float(p[0]), float(p[1])

        a, b = (12.0, 40.0), (300.0, 220.0)
        pl = Placement(a, floor(*a), b, floor(*b))
        got_scale, got_rot, got_shift = pl.similarity()
        assert got_scale == pytest.approx(scale) and got_rot == pytest.approx(rot)
        np.testing.assert_allclose(got_shift, shift, atol=1e-9)
        np.testing.assert_allclose(pl.floor_from_pixel(77.0, 5.0), floor(77.0, 5.0), atol=1e-9)
