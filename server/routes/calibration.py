"""`/robots/{name}/calibration`: calibrate a robot's lens from uploaded chessboard photos."""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Request, UploadFile
from pydantic.json_schema import SkipJsonSchema

from calibration.board import BoardSpec, parse_pattern
from calibration.lens import LensCalibrationConfig, LensModel
from calibration.uploads import calibrate_from_uploads, mounting_kept
from localizer.camera import camera_from_sensor
from server.auth import Operator
from server.deps import RobotName, ServicesDep
from server.stream_guard import stopping
from store.errors import UnavailableError

router = APIRouter(prefix="/robots", tags=["calibration"])

MAX_FILES = 60
MAX_FILE_BYTES = 20 * 1024 * 1024


@router.post("/{name}/calibration/lens")
async def calibrate_lens_upload(
    request: Request,
    name: RobotName,
    services: ServicesDep,
    _: Operator,
    files: Annotated[list[UploadFile], File(description="chessboard or ChArUco photos")],
    pattern: Annotated[str, Form(description="inner corners, columns x rows")] = "9x6",
    square_m: Annotated[float, Form(gt=0, le=1, description="square side, metres")] = 0.025,
    model: Annotated[LensModel, Form()] = "pinhole",
    charuco_dictionary: Annotated[
        str | SkipJsonSchema[None],
        Form(description="a ChArUco board's dictionary, e.g. DICT_5X5_100 (leave out: chessboard)"),
    ] = None,
    marker_m: Annotated[
        float | SkipJsonSchema[None], Form(gt=0, le=1, description="ChArUco marker side, metres")
    ] = None,
    min_views: Annotated[int, Form(ge=3, le=MAX_FILES)] = 5,
    store: Annotated[bool, Form(description="save the result with the robot")] = True,
) -> dict[str, Any]:
    """Calibrate the robot's lens (Zhang, OpenCV) from the uploaded photos.

    The robot's camera mounting (`T_BS`) and frame rate are kept; with `store` the new
    intrinsics replace the robot's. Bad photos, too few views or a wrong pattern end in a 422
    that says what was wrong, and nothing is stored.
    """
    record = services.robot_store.get(name)
    if len(files) > MAX_FILES:
        raise ValueError(f"files: at most {MAX_FILES} photos, got {len(files)}")
    uploads: list[tuple[str, bytes]] = []
    for f in files:
        data = await f.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise ValueError(f"files: {f.filename} is larger than {MAX_FILE_BYTES} bytes")
        uploads.append((f.filename or f"upload{len(uploads)}", data))
    board = BoardSpec(
        pattern=parse_pattern(pattern),
        square_m=square_m,
        kind="charuco" if charuco_dictionary else "chessboard",
        marker_m=marker_m,
        dictionary=charuco_dictionary or BoardSpec.dictionary,
    )
    old = (
        camera_from_sensor(record.camera, source=f"robot {name} camera") if record.camera else None
    )
    halt = stopping(request.app)

    def progress(done: int, total: int) -> None:  # on the worker thread, after each photo
        if halt.is_set():
            raise UnavailableError("the server is shutting down: calibration abandoned")

    options: dict[str, Any] = {
        "progress": progress,
        "model": model,
        "board": board,
        "config": LensCalibrationConfig(min_views=min_views),
        **mounting_kept(old),
    }
    result = await asyncio.to_thread(calibrate_from_uploads, uploads, **options)
    if store:
        services.robots.store_camera(name, result.sensor())
    return {"robot": name, "stored": store, **result.to_dict()}
