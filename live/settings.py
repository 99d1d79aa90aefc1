"""Server settings: environment variables `IRLOC_*`, an optional settings file, CLI flags.

Precedence (highest first): values passed to `Settings(...)` (the CLI flags), environment
variables (`IRLOC_PORT=8001`), the settings file named by `IRLOC_SETTINGS_FILE` (JSON or YAML
with the same field names), the defaults below.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, PydanticBaseSettingsSource, SettingsConfigDict

from fleet.broker import BrokerAddress, parse_broker_url
from fleet.topics import check_name

Source = Literal["sim", "camera", "remote"]


def default_data_dir() -> Path:
    """Per-user data folder: `$XDG_DATA_HOME/irloc`, else `~/.local/share/irloc`."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "irloc"


class _FileSource(PydanticBaseSettingsSource):
    """Reads the settings file named by `IRLOC_SETTINGS_FILE` (JSON or YAML)."""

    def get_field_value(self, field: Any, field_name: str) -> tuple[Any, str, bool]:
        return None, field_name, False

    def __call__(self) -> dict[str, Any]:
        path = os.environ.get("IRLOC_SETTINGS_FILE")
        if not path:
            return {}
        text = Path(path).read_text(encoding="utf-8")
        data = json.loads(text) if path.endswith(".json") else yaml.safe_load(text)
        if data is None:
            return {}
        if not isinstance(data, dict):
            raise ValueError(f"settings file {path}: expected a mapping at the top level")
        return data


SIM_SLEEP_PERIOD_S = 0.5
"""The simulated site's landmarks sleep in cycles of this period unless told otherwise (XBee
`SP`; docs/rf_gateway.md's recommended setting, measured in docs/sim.md, "Landmark battery
benchmark")."""


class Settings(BaseSettings):
    """Everything the server can be told.

    Attributes:
        host, port: where the API listens (loopback by default).
        data_dir: database, recordings; created when missing.
        database_url: SQLAlchemy URL; default `sqlite:///<data_dir>/irloc.db`.
        scenario: the virtual site's scenario (robots with source `sim`).
        radio: `sim` or `xbee:PORT[@BAUD]`.
        map_file: a map.json imported at start (replaces the map), or None.
        seed: the virtual site's random seed.
        site_enabled: run the live site (robots, radio, clock); off for bare API tests.
        viewer_enabled, viewer_port: the viser viewer (port 0: ephemeral).
        pose_queue: poses buffered per pose-bus subscriber before it drops.
        ws_queue: messages buffered per `/poses/ws` client before it drops the oldest.
        ws_flush_s: how long the WebSocket fan-out gathers poses into one message, seconds.
        battery_interval_s: time between battery polls of every landmark; None: never.
        serial_sink: serial port (pyserial URL or device) for the pose lines, or None.
        serial_baud: its baud rate.
        serial_robot: the robot whose poses go to the serial sink (None: every robot).
        log_format: `text` (human-readable lines) or `json` (one JSON object a line).
        allow_remote_viewer_without_auth: never set this on a shared network.
        mqtt_url: the site's MQTT broker, `mqtt://HOST[:PORT]` (None: no fleet; docs/fleet.md).
        mqtt_site: the site's name in the MQTT topics (`irloc/v1/<site>/...`).
        vda_manufacturer: the VDA 5050 manufacturer of the agents (`uagv/v2/<it>/...`).
        alert_webhook_urls: http(s) URLs each alert notification is POSTed to (JSON).
        alert_webhook_secret: key of the webhooks' `X-Irloc-Signature` HMAC (None: none).
        alert_webhook_timeout_s, alert_webhook_retries: one try's timeout; tries after it.
        alert_webhook_max_per_minute: notifications sent to the webhooks a minute at most.
        alert_raise_after_s, alert_clear_after_s, alert_min_interval_s: how long a condition
            holds before it is raised, is absent before it is resolved; the least time
            between two raises of the same alert (docs/alerts.md).
        alert_stale_s: a camera or the wheels silent this long is stale.
        sim_robots: localize the virtual site's robots here (false: the site only, robots
            come as agents).
        led_policy: `scheduled` lights only the landmarks the robots need
            (`live.leds`); `all_lit` lights every landmark (the paper's way);
            `auto` (the default) is `scheduled` with sleeping radios
            (`radio_sleep_period_s`, the simulated site's default), where it meets the
            battery and accuracy targets, and `all_lit` with awake ones, where a listening
            receiver caps a landmark's life at days whatever is lit and the schedule costs
            accuracy (docs/sim.md, "Landmark battery benchmark"). Resolved when
            the settings are made: never `auto` after.
        radio_sleep_period_s: the landmarks' radios sleep in cycles of this period (XBee
            `SP`, 0.32-28 s; the virtual site's radios then sleep too, and LED commands are
            sent that much ahead of need); 0 or None: always-awake radios (`SM=0`). Not
            given: the simulated radio's landmarks sleep at `SIM_SLEEP_PERIOD_S` (modules
            set up as docs/rf_gateway.md recommends), an XBee radio's are taken as awake
            (the modules' own `SM` decides; set this to match them).
        max_body_bytes: a request body's limit where the route sets none larger (413 past
            it; the map, floor plan and lens photos have their own, `server.edge`).
        header_timeout_s: a request's headers must be complete this long after its first
            byte, seconds (else the connection is closed).
        max_connections_per_address, max_connections: open connections per client address
            and in all (the latter also kept under the open-file limit; `server.connections`).
        trusted_proxies: addresses (or networks) of reverse proxies whose `X-Forwarded-For`
            and `X-Forwarded-Proto` are believed; empty (the default): none, the client
            address is the socket's.
        device_dirs: folders (beside the data folder) whose video files a robot's `device`
            may name.
        allow_network_devices: let a robot's `device` be a URL (IP camera) and its
            `wheel_port` a network pyserial URL (`socket://`); off: only local devices.
        recording_max_mb, recording_max_s: a live recording stops (with an event) when it
            passes this size (MB) or duration (s).
        recording_min_free_mb: a recording does not start (507), and stops, when the disk
            has less free space than this (MB).
        black_box_seconds: each robot keeps this many seconds of frames, odometry, LED
            states and poses in memory, saved as a recording on a loss, a suspected kidnap,
            a quality drop or an operator's request (docs/quality.md); 0: no black box.
        black_box_quality_below: a pose's quality falling below this saves the black box.
        black_box_max_mb: the black boxes on disk are kept under this many megabytes
            (the oldest removed first); other recordings are never removed.
    """

    model_config = SettingsConfigDict(env_prefix="IRLOC_", extra="ignore")

    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=0, le=65535)
    data_dir: Path = Field(default_factory=default_data_dir)
    database_url: str | None = None
    scenario: str = "demo"
    radio: str = "sim"
    map_file: Path | None = None
    seed: int = 0
    site_enabled: bool = True
    viewer_enabled: bool = True
    viewer_port: int = Field(default=8080, ge=0, le=65535)
    pose_queue: int = Field(default=256, ge=1)
    ws_queue: int = Field(default=256, ge=1)
    ws_flush_s: float = Field(default=0.005, ge=0.0, le=1.0)
    battery_interval_s: float | None = 3600.0
    serial_sink: str | None = None
    serial_baud: int = 115200
    serial_robot: str | None = None
    log_format: Literal["text", "json"] = "text"
    allow_remote_viewer_without_auth: bool = False
    led_policy: Literal["auto", "scheduled", "all_lit"] = "auto"
    radio_sleep_period_s: float | None = Field(default=None, ge=0.0, le=28.0)
    mqtt_url: str | None = None
    mqtt_password_file: Path | None = None
    mqtt_ca_file: Path | None = None
    mqtt_cert_file: Path | None = None
    mqtt_key_file: Path | None = None
    mqtt_agents: list[str] = Field(default_factory=list)
    mqtt_max_agents: int = Field(default=200, ge=1)
    mqtt_site: str = Field(default="default", pattern=r"^[A-Za-z0-9_.-]{1,64}$")
    vda_manufacturer: str = Field(default="irloc", pattern=r"^[A-Za-z0-9_.-]{1,64}$")
    alert_webhook_urls: list[str] = Field(default_factory=list)
    alert_webhook_secret: SecretStr | None = None
    alert_webhook_timeout_s: float = Field(default=5.0, gt=0.0, le=120.0)
    alert_webhook_retries: int = Field(default=5, ge=0, le=20)
    alert_webhook_max_per_minute: int = Field(default=30, ge=1)
    alert_raise_after_s: float = Field(default=3.0, ge=0.0)
    alert_clear_after_s: float = Field(default=10.0, ge=0.0)
    alert_min_interval_s: float = Field(default=60.0, ge=0.0)
    alert_stale_s: float = Field(default=5.0, gt=0.0)
    sim_robots: bool = True
    max_body_bytes: int = Field(default=1024 * 1024, ge=1024)
    header_timeout_s: float = Field(default=10.0, gt=0.0, le=300.0)
    max_connections_per_address: int = Field(default=512, ge=4)
    max_connections: int = Field(default=4096, ge=16)
    trusted_proxies: list[str] = Field(default_factory=list)
    device_dirs: list[Path] = Field(default_factory=list)
    allow_network_devices: bool = False
    recording_max_mb: int = Field(default=4096, ge=1)
    recording_max_s: float = Field(default=3600.0, gt=0.0)
    recording_min_free_mb: int = Field(default=256, ge=0)
    recordings_keep_days: float | None = Field(default=30.0, gt=0)
    recordings_max_gb: float | None = Field(default=20.0, gt=0)
    history_keep_days: float = Field(default=30.0, gt=0)
    black_box_seconds: float = Field(default=20.0, ge=0.0, le=300.0)
    black_box_quality_below: float = Field(default=0.2, ge=0.0, le=1.0)
    black_box_max_mb: float = Field(default=2000.0, ge=0.0)

    @field_validator("radio")
    @classmethod
    def _check_radio(cls, value: str) -> str:
        text = value.strip()
        if text != "sim" and not text.startswith("xbee:"):
            raise ValueError(f"radio: expected 'sim' or 'xbee:PORT[@BAUD]', got {value!r}")
        return text

    @model_validator(mode="after")
    def _resolve_radio_sleep_and_led_policy(self) -> Settings:
        period = self.radio_sleep_period_s
        if "radio_sleep_period_s" not in self.model_fields_set:
            self.radio_sleep_period_s = SIM_SLEEP_PERIOD_S if self.radio == "sim" else None
        elif period is not None and period <= 0.0:
            self.radio_sleep_period_s = None
        elif period is not None and period < 0.32:
            raise ValueError(
                f"radio_sleep_period_s: 0 (awake) or 0.32-28 s (XBee SP), got {period}"
            )
        if self.led_policy == "auto":
            sleeping = self.radio_sleep_period_s is not None
            self.led_policy = "scheduled" if sleeping else "all_lit"
        return self

    @field_validator("alert_webhook_urls")
    @classmethod
    def _check_webhooks(cls, value: list[str]) -> list[str]:
        from urllib.parse import urlsplit

        for url in value:
            parts = urlsplit(url)
            if parts.scheme not in ("http", "https") or not parts.hostname:
                raise ValueError(f"alert_webhook_urls: {url!r} is not an http(s) URL")
        return value

    @field_validator("trusted_proxies")
    @classmethod
    def _check_proxies(cls, value: list[str]) -> list[str]:
        import ipaddress

        for item in value:
            try:
                ipaddress.ip_network(item, strict=False)
            except ValueError:
                raise ValueError(
                    f"trusted_proxies: {item!r} is not an IP address or network"
                ) from None
        return value

    @model_validator(mode="after")
    def _check_mqtt(self) -> Settings:
        if self.mqtt_url:
            self.broker()
        for name in self.mqtt_agents:
            check_name("mqtt_agents", name.replace("*", "x").replace("?", "x"))
        return self

    def broker(self) -> BrokerAddress:
        """The broker's address and login (`mqtt_url` and the files); ValueError names what
        is wrong."""
        if not self.mqtt_url:
            raise ValueError("mqtt_url: no broker configured")
        return parse_broker_url(
            self.mqtt_url,
            password_file=self.mqtt_password_file,
            ca_file=self.mqtt_ca_file,
            cert_file=self.mqtt_cert_file,
            key_file=self.mqtt_key_file,
        )

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        return (init_settings, env_settings, _FileSource(settings_cls))

    @property
    def db_url(self) -> str:
        """The database URL in force."""
        return self.database_url or f"sqlite:///{self.data_dir / 'irloc.db'}"

    @property
    def recordings_dir(self) -> Path:
        return self.data_dir / "recordings"
