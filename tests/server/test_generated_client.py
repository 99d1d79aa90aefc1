"""A client generated from `/openapi.json` with openapi-python-client lists landmarks, reads a
robot's pose and replaces the map against a live server (real uvicorn, the virtual site)."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.server.live_server import LiveApi, live_api

pytestmark = pytest.mark.slow
GENERATOR = Path(sys.executable).parent / "openapi-python-client"
BINARY_OR_CSV = ("text/csv", "image/png", "image/jpeg")


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveApi]:
    with live_api(tmp_path_factory.mktemp("client"), scenario="paper_testbed") as api:
        yield api


def _generate(url: str, out: Path) -> tuple[Any, str]:
    spec = out / "openapi.json"
    spec.write_text(httpx.get(f"{url}/openapi.json").text)
    done = subprocess.run(
        [str(GENERATOR), "generate", "--path", str(spec), "--meta", "none",
         "--output-path", str(out / "irloc_client")],
        capture_output=True, text=True, timeout=120, cwd=out,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    sys.path.insert(0, str(out))
    try:
        return importlib.import_module("irloc_client"), done.stdout + done.stderr
    finally:
        sys.path.remove(str(out))


def test_a_generated_client_lists_reads_a_pose_and_replaces_the_map(
    live: LiveApi, tmp_path: Path
) -> None:
    client_pkg, log = _generate(live.url, tmp_path)
    # every operation generated but for bodies a generator cannot type: CSV and images
    warnings = [line for line in log.splitlines() if line.startswith(("WARNING", "Unsupported"))]
    assert warnings, log
    for line in warnings:
        assert line.startswith(("WARNING parsing", "Unsupported content type")), line
        assert line.startswith("WARNING") or line.split()[-1] in BINARY_OR_CSV, line
    landmarks = importlib.import_module("irloc_client.api.landmarks.list_landmarks")
    pose = importlib.import_module("irloc_client.api.robots.get_robot_pose")
    replace = importlib.import_module("irloc_client.api.map_.replace_map")
    models = importlib.import_module("irloc_client.models")
    client = client_pkg.AuthenticatedClient(base_url=live.url, token=live.keys["admin"])

    listed = landmarks.sync(client=client)
    assert isinstance(listed, list) and len(listed) == len(live.services.map.list()) > 0
    first = listed[0]
    assert isinstance(first, models.LandmarkPublic) and 0 < first.z < 10

    robot = live.services.robots.names()[0]
    got = pose.sync_detailed(name=robot, client=client)
    assert got.status_code == 200, got.content
    assert got.parsed.robot == robot and got.parsed.mode in ("landmark", "identifying",
                                                             "dead_reckoning", "lost")  # fmt: skip

    doc = models.MapDocument.from_dict(
        {"landmarks": [{"id": 7, "x": 1.0, "y": 2.0, "z": 2.5, "radio": "0013A20041B2C3D4"},
                       {"id": 8, "x": 1.75, "y": 2.0, "z": 2.5}]}
    )  # fmt: skip
    result = replace.sync(client=client, body=doc)
    assert isinstance(result, models.ImportResult) and result.landmarks == 2
    assert [(lm.id, lm.x) for lm in landmarks.sync(client=client)] == [(7, 1.0), (8, 1.75)]
    # errors are typed too: an empty map needs allow_empty
    empty = replace.sync_detailed(
        client=client, body=models.MapDocument.from_dict({"landmarks": []})
    )
    assert empty.status_code == 409 and "allow_empty" in empty.parsed.detail
    # a viewer key: 403 parsed as ErrorResponse
    viewer = client_pkg.AuthenticatedClient(base_url=live.url, token=live.keys["viewer"])
    refused = replace.sync_detailed(client=viewer, body=doc)
    assert refused.status_code == 403 and isinstance(refused.parsed, models.ErrorResponse)
    assert json.loads(refused.content)["detail"].startswith("this needs the admin role")


def test_a_generated_client_does_what_the_viewer_does(live: LiveApi, tmp_path: Path) -> None:
    """The viewer's actions through the generated client: the floor plan uploaded as a file,
    the map imported from CSV, a robot relocalized and its stale pose read, events filtered
    by kind, a recording made, listed, downloaded and deleted."""
    import io
    import zipfile

    import cv2
    import numpy as np

    client_pkg, log = _generate(live.url, tmp_path)
    for bare in ("put_floorplan", "replace_map"):  # no operation lost its body
        assert not any(bare in line for line in log.splitlines() if "WARNING" in line), log
    api = "irloc_client.api"
    types = importlib.import_module("irloc_client.types")
    models = importlib.import_module("irloc_client.models")
    client = client_pkg.AuthenticatedClient(base_url=live.url, token=live.keys["admin"])

    put_plan = importlib.import_module(f"{api}.map_.put_floorplan")
    ok, png = cv2.imencode(".png", np.full((60, 80, 3), 200, np.uint8))
    assert ok
    plan = types.File(payload=io.BytesIO(png.tobytes()), file_name="plan.png",
                      mime_type="application/octet-stream")  # fmt: skip
    got = put_plan.sync_detailed(client=client, body=plan, a_px=[0, 0], a_m=[0, 6], b_px=[80, 0],
                                 b_m=[8, 6])  # fmt: skip
    assert got.status_code == 200, got.content
    assert json.loads(got.content)["width_px"] == 80

    replace = importlib.import_module(f"{api}.map_.replace_map")
    csv = b"id,x,y,z,radio\n7,1.0,2.0,2.5,0013A20041B2C3D4\n8,1.75,2.0,2.5,\n"
    as_file = types.File(payload=io.BytesIO(csv), file_name="map.csv",
                         mime_type="application/octet-stream")  # fmt: skip
    got = replace.sync_detailed(client=client, body=as_file)
    assert got.status_code == 200 and json.loads(got.content)["landmarks"] == 2, got.content

    robot = live.services.robots.names()[0]
    relocalize = importlib.import_module(f"{api}.robots.relocalize_robot")
    # (the optional position hint: None, as the generated client cannot leave the body out)
    assert relocalize.sync_detailed(name=robot, client=client, body=None).status_code == 202
    pose = importlib.import_module(f"{api}.robots.get_robot_pose").sync(name=robot, client=client)
    assert isinstance(pose, models.PosePublic) and isinstance(pose.stale, bool)

    events = importlib.import_module(f"{api}.streams.list_events")
    kind = models.ListEventsKindType0Item("map_changed")
    changed = events.sync(client=client, kind=[kind], limit=5)
    assert changed and all(e.kind.value == "map_changed" for e in changed)

    robots = f"{api}.robots"
    start = importlib.import_module(f"{robots}.start_robot_recording").sync(
        name=robot, client=client
    )
    importlib.import_module(f"{robots}.stop_robot_recording").sync(name=robot, client=client)
    rec = f"{api}.recordings"
    listed = importlib.import_module(f"{rec}.list_recordings").sync(client=client, robot=robot)
    assert [r.name for r in listed] == [start.name] and listed[0].trigger == "manual"
    zipped = importlib.import_module(f"{rec}.download_recording").sync_detailed(
        name=start.name, client=client
    )
    assert zipped.status_code == 200
    assert f"{start.name}/map.json" in zipfile.ZipFile(io.BytesIO(zipped.content)).namelist()
    delete = importlib.import_module(f"{rec}.delete_recording")
    assert delete.sync_detailed(name=start.name, client=client).status_code == 409
    assert delete.sync_detailed(name=start.name, client=client, confirm=True).status_code == 204
