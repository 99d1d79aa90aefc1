"""The incremental survey's state in a file (`save`, `load`: numpy's .npz, its bookkeeping
as JSON inside, no pickle), so that a live survey's running estimate survives a restart of
the server (live/survey/estimator.py)."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from survey.incremental import IncrementalSurvey
from survey.marginal import WindowPrior
from survey.result import LandmarkEstimate, SurveyResult
from survey.tally import Tally


def save(state: IncrementalSurvey, path: Path, extra: dict[str, object] | None = None) -> None:
    """Write `state` (and `extra`, JSON: what the caller needs to resume) to `path`
    atomically (a crash mid-write leaves the previous file)."""
    arrays = to_arrays(state)
    arrays["extra"] = np.array(json.dumps(extra or {}))
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy's stub: allow_pickle
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load(path: Path) -> tuple[IncrementalSurvey, dict[str, object]]:
    """The state `save` wrote, and its `extra`. ValueError when the file is not one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as exc:
        raise ValueError(f"{path}: not a survey state ({exc})") from None
    extra = json.loads(str(arrays.pop("extra", np.array("{}"))))
    return from_arrays(arrays), extra if isinstance(extra, dict) else {}


def _result_json(r: SurveyResult) -> dict[str, object]:
    return {
        "landmarks": [
            {
                "id": e.id,
                "position": e.position.tolist(),
                "covariance": e.covariance.tolist(),
                "anchor": e.anchor,
                "observations": e.observations,
                "views": e.views,
                "rms_px": e.rms_px,
                "max_px": e.max_px,
                "given": None if e.given is None else e.given.tolist(),
                "flags": list(e.flags),
            }
            for e in r.landmarks.values()
        ],
        "unseen": list(r.unseen),
        "wheels": list(r.wheel_calibration),
        "camera": list(r.camera_correction),
        "rms_px": r.rms_px,
        "sigma_scale": r.sigma_scale,
        "iterations": r.iterations,
        "converged": r.converged,
        "notes": list(r.notes),
        "unnamed": {str(k): v for k, v in r.unnamed.items()},
    }


def _result_from(d: dict[str, Any]) -> SurveyResult:  # JSON as `_result_json` wrote it
    lms = {}
    for e in d["landmarks"]:
        lms[int(e["id"])] = LandmarkEstimate(
            int(e["id"]),
            np.array(e["position"], dtype=np.float64),
            np.array(e["covariance"], dtype=np.float64).reshape(3, 3),
            bool(e["anchor"]),
            int(e["observations"]),
            int(e["views"]),
            float(e["rms_px"]),
            float(e["max_px"]),
            None if e["given"] is None else np.array(e["given"], dtype=np.float64),
            tuple(str(f) for f in e["flags"]),
        )
    return SurveyResult(
        lms,
        tuple(int(i) for i in d["unseen"]),
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 3)),
        (float(d["wheels"][0]), float(d["wheels"][1]), float(d["wheels"][2])),
        tuple(float(v) for v in d["camera"]),
        float(d["rms_px"]),
        float(d["sigma_scale"]),
        int(d["iterations"]),
        bool(d["converged"]),
        tuple(str(n) for n in d["notes"]),
        {int(k): str(v) for k, v in d["unnamed"].items()},
    )


def _tally_json(t: Tally) -> dict[str, object]:
    return dataclasses.asdict(t)


def to_arrays(state: IncrementalSurvey) -> dict[str, npt.NDArray[np.generic]]:
    """The state as named arrays (`numpy.savez`), its latest estimate included."""
    p = state.prior
    meta = {
        "version": 1,
        "updates": state.updates,
        "carried": {str(k): _tally_json(v) for k, v in state.carried.items()},
        "result": None if state.result is None else _result_json(state.result),
    }
    out: dict[str, npt.NDArray[np.generic]] = {
        "meta": np.array(json.dumps(meta)),
        "trajectory_t_ns": state.trajectory_t_ns,
        "trajectory": state.trajectory,
    }
    if p is not None:
        out |= {
            "prior_t_ns": np.array(p.t_ns, dtype=np.int64),
            "prior_ids": np.array(p.landmark_ids, dtype=np.int64),
            "prior_mean": p.mean,
            "prior_information": p.information,
            "prior_lead_t_ns": p.lead_t_ns,
            "prior_lead_poses": p.lead_poses,
            "prior_scales": np.array([p.pixel_scale, p.odometry_scale, float(p.has_pose)]),
        }
    return out


def from_arrays(arrays: dict[str, npt.NDArray[np.generic]]) -> IncrementalSurvey:
    """The state `to_arrays` wrote. ValueError when it is not one."""
    try:
        meta = json.loads(str(arrays["meta"]))
        if meta.get("version") != 1:
            raise ValueError(f"version {meta.get('version')!r}")
        carried = {}
        for k, v in meta["carried"].items():
            v = dict(v)
            for name in ("first_view", "last_view"):
                if v[name] is not None:
                    v[name] = (float(v[name][0]), float(v[name][1]))
            carried[int(k)] = Tally(**v)
        prior = None
        if "prior_mean" in arrays:
            sc = np.asarray(arrays["prior_scales"], dtype=np.float64)
            prior = WindowPrior(
                int(np.asarray(arrays["prior_t_ns"])),
                tuple(int(i) for i in np.asarray(arrays["prior_ids"]).tolist()),
                np.asarray(arrays["prior_mean"], dtype=np.float64),
                np.asarray(arrays["prior_information"], dtype=np.float64),
                np.asarray(arrays["prior_lead_t_ns"], dtype=np.int64),
                np.asarray(arrays["prior_lead_poses"], dtype=np.float64).reshape(-1, 3),
                float(sc[0]),
                float(sc[1]),
                bool(sc[2]),
            )
        return IncrementalSurvey(
            prior,
            np.asarray(arrays["trajectory_t_ns"], dtype=np.int64),
            np.asarray(arrays["trajectory"], dtype=np.float64).reshape(-1, 3),
            carried,
            None if meta.get("result") is None else _result_from(meta["result"]),
            int(meta["updates"]),
        )
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as exc:
        raise ValueError(f"not a survey state ({exc})") from None
