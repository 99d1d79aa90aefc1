"""`config_from_dict`: settings files checked key by key, errors naming the key."""

from __future__ import annotations

import pytest

from localizer.config import LocalizerConfig
from localizer.config_dict import ConfigError, config_from_dict, config_to_dict


def test_round_trip_of_every_default() -> None:
    assert config_from_dict(config_to_dict(LocalizerConfig())) == LocalizerConfig()
    assert config_from_dict(None) == LocalizerConfig()
    assert config_from_dict({}) == LocalizerConfig()


def test_only_the_given_keys_change_and_numbers_are_coerced() -> None:
    cfg = config_from_dict(
        {
            "detection": {"max_area_px": 1500, "max_elongation": 4, "threshold_counts": None},
            "filter": {"calibration_bounds": [0.9, 1.1]},
            "identification": {"probe": "light_one"},
            "fusion": {"robust_loss": None},
        }
    )
    assert cfg.detection.max_area_px == 1500
    assert cfg.detection.max_elongation == 4.0 and isinstance(cfg.detection.max_elongation, float)
    assert cfg.filter.calibration_bounds == (0.9, 1.1)
    assert cfg.identification.probe == "light_one"
    assert cfg.fusion.robust_loss is None
    assert cfg.tracking == LocalizerConfig().tracking


@pytest.mark.parametrize(
    ("data", "key", "what"),
    [
        ({"detecton": {}}, "detecton", "unknown setting"),
        ({"detection": {"max_area": 3}}, "detection.max_area", "unknown setting"),
        ({"detection": {"max_area_px": 2.5}}, "detection.max_area_px", "expected an integer"),
        ({"detection": {"max_area_px": True}}, "detection.max_area_px", "expected an integer"),
        ({"tracking": {"sigma_gate": "4"}}, "tracking.sigma_gate", "expected a number"),
        ({"tracking": {"sigma_gate": float("nan")}}, "tracking.sigma_gate", "finite"),
        ({"filter": {"adapt_noise": 1}}, "filter.adapt_noise", "expected true or false"),
        ({"filter": {"calibration_bounds": [1]}}, "filter.calibration_bounds", "list of 2"),
        ({"identification": {"probe": "blink"}}, "identification.probe", "expected one of"),
        ({"motion": 3}, "motion", "expected a mapping"),
        # a sub-config's own check, named by its section
        ({"detection": {"min_area_px": 5, "max_area_px": 4}}, "detection", "max_area_px"),
        ({"motion": {"accel_sigma_m_s2": 0}}, "motion", "accel_sigma_m_s2"),
    ],
)
def test_bad_settings_name_the_key(data: dict[str, object], key: str, what: str) -> None:
    with pytest.raises(ConfigError) as info:
        config_from_dict(data)
    assert info.value.key == key
    assert str(info.value).startswith(f"{key}: ")
    assert what in str(info.value)


def test_per_mode_settings_are_read_and_an_unknown_mode_is_named() -> None:
    cfg = config_from_dict({"quality": {"heading_scale": {"landmark": 1.2}}})
    assert cfg.quality.heading_scale == {"landmark": 1.2}
    with pytest.raises(ConfigError, match=r"quality.*unknown mode 'landmrk'"):
        config_from_dict({"quality": {"heading_scale": {"landmrk": 1.2}}})
    with pytest.raises(ConfigError, match=r"quality\.heading_scale\.landmark: expected a number"):
        config_from_dict({"quality": {"heading_scale": {"landmark": "big"}}})


def test_the_quality_modes_are_the_localizers() -> None:
    from localizer import events, pose_quality

    assert set(pose_quality.MODES) == set(events.MODES)


def test_a_retired_key_of_an_older_settings_file_is_ignored_and_a_misspelt_one_is_not() -> None:
    older = {"fusion": {"full_frame_every_s": 0.0, "nis_gate": 12.0}}
    assert config_from_dict(older).fusion.nis_gate == 12.0
    with pytest.raises(ConfigError, match=r"fusion\.full_frame_every"):
        config_from_dict({"fusion": {"full_frame_every": 0.0}})
