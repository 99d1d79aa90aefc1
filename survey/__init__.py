"""Surveying the landmarks by driving under them: identification by blinks, spot tracks,
and a bundle adjustment of the robot's trajectory and every landmark position at once.

See `docs/survey.md`. The estimation modules are pure (numpy in, numpy out); `survey.cli`
reads a recording and writes a map (`irloc survey`).
"""

from survey.blinks import BlinkConfig, blink_schedule
from survey.bundle import solve_survey
from survey.observations import LabelledObservations, TrackingConfig, label_spot_tracks
from survey.problem import BundleConfig, SurveyProblem
from survey.result import LandmarkEstimate, SurveyResult

__all__ = [
    "BlinkConfig",
    "BundleConfig",
    "LabelledObservations",
    "LandmarkEstimate",
    "SurveyProblem",
    "SurveyResult",
    "TrackingConfig",
    "blink_schedule",
    "label_spot_tracks",
    "solve_survey",
]
