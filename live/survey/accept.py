"""Accepting a survey's proposals: which landmarks may be written, and the edits that write
them with their uncertainty and evidence (`LiveSurvey.accept`)."""

from __future__ import annotations

from store.models import LandmarkUpdate
from survey.result import LandmarkEstimate


def check_choice(
    chosen: list[int],
    free: dict[int, LandmarkEstimate],
    include_flagged: bool,
    locked: set[int],
) -> None:
    """ValueError naming every ID of `chosen` that cannot be accepted."""
    twice = sorted({i for i in chosen if chosen.count(i) > 1})
    if twice:
        raise ValueError(f"landmarks: {', '.join(map(str, twice))} given more than once")
    missing = sorted(set(chosen) - set(free))
    if missing:
        raise ValueError(
            f"landmarks: {', '.join(map(str, missing))} not surveyed (or anchors); "
            f"surveyed: {', '.join(map(str, sorted(free))) or 'none yet'}"
        )
    now_locked = sorted(set(chosen) & locked)
    if now_locked:
        raise ValueError(
            f"landmarks: {', '.join(map(str, now_locked))} are locked in the map (anchors): "
            "unlock them first to overwrite their surveyed positions"
        )
    flagged = [i for i in chosen if free[i].flags]
    if flagged and not include_flagged:
        names = "; ".join(f"{i}: {', '.join(free[i].flags)}" for i in flagged)
        raise ValueError(
            f"landmarks flagged by the survey ({names}): check them, or accept them anyway "
            "with include_flagged"
        )


def accepted_edits(
    chosen: list[int], free: dict[int, LandmarkEstimate]
) -> list[tuple[int, LandmarkUpdate]]:
    """The map edits of `chosen`: each position with its sigma, covariance and evidence."""
    edits = []
    for lid in chosen:
        e = free[lid]
        x, y, z = (float(v) for v in e.position)
        evidence = {
            "source": "survey",
            "views": e.views,
            "observations": e.observations,
            "rms_px": round(e.rms_px, 3),
        }
        update = LandmarkUpdate(
            x=x,
            y=y,
            z=z,
            sigma_m=e.sigma_m,
            covariance=e.covariance.tolist(),
            evidence=evidence,
        )
        edits.append((lid, update))
    return edits
