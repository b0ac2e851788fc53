"""Simulator configuration: typed records, built-in profiles and YAML loading.

A configuration is a YAML mapping. It may name a base ``profile`` (built-in or a file);
its own keys are then merged over the base, key by key. Unknown keys and values of the
wrong type are errors (:class:`~ofbe_data.core.errors.ConfigError`) naming the key.
docs/sensor-model.md gives the source of every default.

``duts`` is a list of devices, a mapping ``{id: {...}}``, or, for fleets, the compact form
``{count: 300, prefix: unit-}`` (:func:`expand_duts`): ``count`` devices ``unit-001`` …
``unit-300``, optionally with ``start`` (first number, 1), ``digits`` (3) and the settings every
device shares (``up_axis``, ``reference_to_sensor``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.formats import reference_formats
from ofbe_data.io.manifest import ID_PATTERN
from ofbe_data.io.mappings import deep_merge
from ofbe_data.io.typedconfig import from_plain
from ofbe_data.io.yamlio import YamlDocument, YamlProblem, read_yaml
from ofbe_data.simulator.wearconfig import FREE_LIVING, FreeLivingConfig, check_free_living

Range = tuple[float, float]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class DutConfig:
    """One device under test (SparkFun Thing Plus ESP32 + ADXL345).

    Attributes
    ----------
    id
        Device id.
    reference_to_sensor
        Nominal rotation from the reference (plate) frame to this sensor's frame.
    up_axis
        For level (gravity-aligned) placement: the sensor axis pointing up, e.g. ``+z``.
    """

    id: str
    reference_to_sensor: tuple[Vec3, Vec3, Vec3] = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    up_axis: str = "+z"


@dataclass(frozen=True)
class ReferenceConfig:
    """The reference IMU (Memsense MS-IMU3025)."""

    id: str = "memsense"
    serial: str = "3025-00417"


@dataclass(frozen=True)
class DutModel:
    """Error model and logger settings of the ADXL345 devices (all per axis x, y, z)."""

    lsb_per_g: float = 256.0
    range_g: int = 16
    scale_sigma: float = 0.01
    cross_axis_sigma_deg: float = 0.3
    mount_sigma_deg: float = 1.5
    offset_sigma_mg: Vec3 = (12.0, 12.0, 20.0)
    turn_on_sigma_mg: Vec3 = (5.0, 5.0, 5.0)
    drift_sigma_mg: float = 0.3
    drift_tau_s: float = 100.0
    warmup_mg: Vec3 = (0.0, 0.0, 0.0)
    warmup_tau_s: float = 120.0
    noise_mg: Vec3 = (3.5, 3.5, 5.2)
    rate_hz: float = 150.0
    jitter_s: float = 0.0002
    drop_prob: float = 2e-4
    clock_ppm: float = 50.0
    uptime_s: Range = (3.0, 4294.0)
    host_latency_s: float = 0.1
    boot_lines: tuple[int, int] = (1, 4)
    garble_rate: float = 2e-5
    firmware: str = "1.4.2"


@dataclass(frozen=True)
class ReferenceModel:
    """Error model of the reference IMU."""

    rate_hz: float = 200.0
    bias_sigma_mg: float = 0.395
    noise_mg: float = 0.5
    scale_sigma: float = 0.0002
    cross_axis_sigma_deg: float = 0.01
    gyro_noise_dps: float = 0.01
    temperature_c: float = 31.2


@dataclass(frozen=True)
class TiltConfig:
    """Orientations of the plate (or of level devices).

    ``mode``: ``level`` (gravity-aligned: each device rests with ``up_axis`` up, tilted
    only by ``level_sigma_deg``), ``rotated`` (tripod settings drawn over the pitch and
    roll ranges, a third roll-only, a third pitch-only, a third combined), or
    ``multi-position`` (per session the six faces, then random orientations).
    """

    mode: str = "rotated"
    pitch_deg: Range = (-80.0, 60.0)
    roll_deg: Range = (-180.0, 180.0)
    setting_step_deg: float = 1.0
    setting_error_deg: float = 0.5
    level_sigma_deg: float = 0.2
    face_error_deg: float = 2.0


@dataclass(frozen=True)
class TapConfig:
    """Taps on the plate at the start and end of a recording."""

    enabled: bool = True
    lead_s: Range = (2.0, 4.0)
    tail_s: Range = (2.0, 4.0)
    amplitude_g: Range = (0.5, 3.0)
    frequency_hz: Range = (25.0, 40.0)
    decay_s: float = 0.05
    margin_s: float = 1.0
    start_stagger_s: float = 1.0


@dataclass(frozen=True)
class ContinuousConfig:
    """Continuous multi-position recordings: many poses per recording, handling between them.

    Each recording holds K poses (K uniform in ``poses``), the device resting ``pose_s`` in
    each and turned by hand for ``handling_s`` between them (a minimum-jerk rotation with a
    wobble, a lift, tremor and the jolts of taking and setting down the device). A recording
    starts at rest in its first pose (a quiet stretch of ``quiet_s`` more; probability
    ``quiet_start_prob``) or with the device being handled into it; it ends with the device
    picked up. No taps: ``taps`` and ``stationary_s`` do not apply (``taps.start_stagger_s``
    still staggers the loggers' starts).

    Attributes
    ----------
    poses
        Fewest and most poses per recording (integers, inclusive).
    pose_s
        Rest in each pose, s (uniform range).
    handling_s
        Handling between two poses, before the first (recordings that start moving) and after
        the last, s (uniform range).
    quiet_s
        Quiet stretch before the first pose's ``pose_s`` in recordings that start at rest, s.
    quiet_start_prob
        Probability that a recording starts at rest rather than moving.
    """

    poses: tuple[int, int] = (6, 40)
    pose_s: Range = (1.0, 10.0)
    handling_s: Range = (1.0, 4.0)
    quiet_s: Range = (1.0, 3.0)
    quiet_start_prob: float = 0.5


@dataclass(frozen=True)
class SimConfig:
    """A whole simulated campaign.

    Attributes
    ----------
    kind
        ``gravity-aligned``, ``rotated``, ``multi-position`` or ``free-living``.
    campaign
        Campaign id; None → the output folder's name.
    session_prefix
        Session ids are ``<prefix>-pc<NNN>``.
    sessions
        Number of sessions (power cycles).
    recordings_per_session
        Recordings per power cycle.
    stationary_s
        Duration of the stationary part of each recording, s (uniform range).
    seed
        Default seed (``--seed`` overrides).
    start_utc
        UTC of the first power-on.
    site
        ``latitude_deg``/``height_m`` or ``gravity_mps2``.
    duts, reference
        Devices; ``reference`` None for campaigns without one.
    reference_format
        File format of the reference's recordings: ``mscip-csv`` (the default) or ``mscip-bin``
        (the MSCIP byte stream, ``<reference id>.bin``).
    continuous
        Multi-position campaigns only: recordings of many poses with handling between them
        (:class:`ContinuousConfig`); None (the default) → one pose per recording, between taps.
    free_living
        Free-living campaigns only: wearables worn for days
        (:class:`~ofbe_data.simulator.wearconfig.FreeLivingConfig`; its defaults when None).
    """

    kind: str = "rotated"
    campaign: str | None = None
    session_prefix: str = "sim"
    sessions: int = 29
    recordings_per_session: int = 3
    stationary_s: Range = (80.25, 93.0)
    seed: int = 0
    start_utc: str = "2025-03-14T09:00:00Z"
    site: dict[str, float] = field(default_factory=lambda: {"latitude_deg": 32.794,
                                                             "height_m": 35.0})
    duts: tuple[DutConfig, ...] = (DutConfig("sparkfun-1"),)
    reference: ReferenceConfig | None = None
    dut_model: DutModel = DutModel()
    reference_model: ReferenceModel = ReferenceModel()
    tilts: TiltConfig = TiltConfig()
    taps: TapConfig = TapConfig()
    reference_format: str = "mscip-csv"
    continuous: ContinuousConfig | None = None
    free_living: FreeLivingConfig | None = None


DEFAULT_REFERENCE_FORMAT: str = SimConfig.reference_format
"""The reference's format when a configuration sets none (:class:`SimConfig`'s default). Any
reference format of the registry (:func:`ofbe_data.io.formats.reference_formats`) may be set;
``simulator/writing.py`` writes ``mscip-bin`` with its writer and any other with the
``mscip-csv`` writer, so a new reference format needs its writer there too."""

# ----------------------------------------------------------------------------- loading

_PROFILE_PACKAGE = "ofbe_data.simulator.profiles"


def builtin_profiles() -> list[str]:
    """Names of the built-in profiles."""
    files = resources.files(_PROFILE_PACKAGE).iterdir()
    return sorted(p.name[:-5] for p in files if p.name.endswith(".yaml"))


def _load_raw(name_or_path: str | Path, chain: tuple[str, ...] = ()) -> dict[str, Any]:
    """Resolve a profile name or YAML file into one plain mapping (bases merged)."""
    text_source = str(name_or_path)
    if text_source in chain:
        raise ConfigError(text_source, "profile", "no cycle of base profiles",
                          " -> ".join((*chain, text_source)))
    path = Path(name_or_path)
    try:
        if path.suffix in (".yaml", ".yml") or path.exists():
            if not path.is_file():
                raise ConfigError(path, "<file>", "a YAML config file or a built-in profile ("
                                  + ", ".join(builtin_profiles()) + ")", "no such file")
            doc = read_yaml(path)
        else:
            res = resources.files(_PROFILE_PACKAGE).joinpath(f"{text_source}.yaml")
            if not res.is_file():
                raise ConfigError(text_source, "profile", "a built-in profile ("
                                  + ", ".join(builtin_profiles()) + ") or a YAML file",
                                  "no such profile")
            doc = YamlDocument(res.read_text(encoding="utf-8"))
    except YamlProblem as exc:
        where = f"{text_source}:{exc.line}" if exc.line else text_source
        raise ConfigError(where, exc.field, exc.expected, exc.found) from None
    data = doc.data if doc.data is not None else {}
    if not isinstance(data, dict):
        raise ConfigError(text_source, "<document>", "a mapping", type(data).__name__)
    base = data.pop("profile", None)
    if base is None:
        return data
    if not isinstance(base, str):
        raise ConfigError(text_source, "profile", "a profile name or file", repr(base))
    if not Path(base).is_absolute() and Path(base).suffix in (".yaml", ".yml") and path.is_file():
        base = str(path.parent / base)
    return deep_merge(_load_raw(base, (*chain, text_source)), data)


MAX_STATIONARY_S = 86_400.0
"""Longest stationary recording the simulator makes, s: a day at 150 Hz is 13 M samples a file."""

def _check(cfg: SimConfig, source: str) -> SimConfig:
    """Semantic checks that types alone do not catch."""
    kinds = ("gravity-aligned", "rotated", "multi-position", FREE_LIVING)
    if cfg.kind not in kinds:
        raise ConfigError(source, "kind", "one of " + ", ".join(kinds), repr(cfg.kind))
    if cfg.kind == "rotated" and cfg.reference is None:
        raise ConfigError(source, "reference", "a reference device for kind rotated", "none")
    if cfg.kind != "rotated" and cfg.reference is not None:
        raise ConfigError(source, "reference", f"no reference for kind {cfg.kind}", "one")
    if cfg.reference_format not in reference_formats():
        raise ConfigError(source, "reference_format", "one of " + ", ".join(reference_formats()),
                          repr(cfg.reference_format))
    if cfg.reference is None and cfg.reference_format != DEFAULT_REFERENCE_FORMAT:
        raise ConfigError(source, "reference_format", f"{DEFAULT_REFERENCE_FORMAT} (the default) for a "
                          f"campaign without a reference (kind {cfg.kind})", repr(cfg.reference_format))
    if not cfg.duts:
        raise ConfigError(source, "duts", "at least one device", "none")
    if len({d.id for d in cfg.duts}) != len(cfg.duts):
        raise ConfigError(source, "duts", "unique device ids", repr([d.id for d in cfg.duts]))
    for name in ("sessions", "recordings_per_session"):
        if getattr(cfg, name) < 1:
            raise ConfigError(source, name, "an integer >= 1", repr(getattr(cfg, name)))
    lo, hi = cfg.stationary_s
    if not 0 < lo <= hi:
        raise ConfigError(source, "stationary_s", "0 < low <= high", repr(cfg.stationary_s))
    if cfg.kind != FREE_LIVING and cfg.free_living is not None:
        raise ConfigError(source, "free_living", f"no free_living section for kind {cfg.kind}", "one")
    if cfg.kind == FREE_LIVING:  # no tilts, taps or stationary recordings
        if cfg.continuous is not None:
            _check_continuous(cfg.continuous, cfg.kind, source)  # refused: multi-position only
        check_free_living(cfg.free_living or FreeLivingConfig(), source)
        return cfg
    if hi > MAX_STATIONARY_S:
        raise ConfigError(source, "stationary_s", f"at most {MAX_STATIONARY_S:g} s (one day) per recording",
                          repr(cfg.stationary_s))
    modes = {"gravity-aligned": "level", "rotated": "rotated", "multi-position": "multi-position"}
    if cfg.tilts.mode != modes[cfg.kind]:
        raise ConfigError(source, "tilts.mode", f"{modes[cfg.kind]} for kind {cfg.kind}",
                          repr(cfg.tilts.mode))
    for d in cfg.duts:
        if d.up_axis not in ("+x", "-x", "+y", "-y", "+z", "-z"):
            raise ConfigError(source, f"duts.{d.id}.up_axis", "one of +x -x +y -y +z -z",
                              repr(d.up_axis))
    m = cfg.dut_model
    if not 0 <= m.drop_prob < 0.5 or not 0 <= m.garble_rate < 0.5:
        raise ConfigError(source, "dut_model.drop_prob/garble_rate", "probabilities in [0, 0.5)",
                          f"{m.drop_prob}, {m.garble_rate}")
    if m.uptime_s[0] < 0 or m.uptime_s[1] < m.uptime_s[0]:
        raise ConfigError(source, "dut_model.uptime_s", "0 <= low <= high", repr(m.uptime_s))
    if m.jitter_s * m.rate_hz >= 0.25:
        raise ConfigError(source, "dut_model.jitter_s", "less than a quarter sample period",
                          repr(m.jitter_s))
    if cfg.continuous is not None:
        _check_continuous(cfg.continuous, cfg.kind, source)
    return cfg


MAX_POSES = 1000
"""Most poses per continuous recording."""


def _check_continuous(c: ContinuousConfig, kind: str, source: str) -> None:
    """Semantic checks of the ``continuous`` section."""
    if kind != "multi-position":
        raise ConfigError(source, "continuous", f"no continuous section for kind {kind} "
                          "(multi-position only)", "one")
    lo, hi = c.poses
    if not 1 <= lo <= hi <= MAX_POSES:
        raise ConfigError(source, "continuous.poses", f"1 <= low <= high <= {MAX_POSES}", repr(c.poses))
    for name in ("pose_s", "handling_s", "quiet_s"):
        low, high = getattr(c, name)
        if not 0 < low <= high:
            raise ConfigError(source, f"continuous.{name}", "0 < low <= high", repr(getattr(c, name)))
    if not 0.0 <= c.quiet_start_prob <= 1.0:
        raise ConfigError(source, "continuous.quiet_start_prob", "a probability in [0, 1]",
                          repr(c.quiet_start_prob))
    longest = hi * (c.pose_s[1] + c.handling_s[1]) + c.handling_s[1] + c.quiet_s[1]
    if longest > MAX_STATIONARY_S:
        raise ConfigError(source, "continuous", f"recordings of at most {MAX_STATIONARY_S:g} s (one day)",
                          f"up to {longest:g} s")


MAX_FLEET_DUTS = 100_000
"""Most devices the compact ``duts: {count: ...}`` form declares."""

_FLEET_KEYS = ("count", "prefix", "start", "digits", "up_axis", "reference_to_sensor")


def _fleet_int(spec: dict[str, Any], key: str, default: int, low: int, high: int, source: str) -> int:
    value = spec.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigError(source, f"duts.{key}", f"an integer in {low}..{high}", repr(value))
    return value


def expand_duts(duts: Any, source: str = "<config>") -> Any:
    """The plain ``duts`` list of a configuration, its compact forms expanded.

    Parameters
    ----------
    duts
        A list of device mappings (returned as is), a mapping ``{id: {...} or null}``, or the
        fleet form ``{count: N, prefix: unit-, start: 1, digits: 3, up_axis: ...,
        reference_to_sensor: ...}`` (only ``count`` required): N devices
        ``<prefix><start:0{digits}d>`` … sharing the optional settings.
    source
        File or name for error messages.

    Returns
    -------
    list or the input unchanged
        ``[{"id": ..., ...}, ...]`` for the mapping forms; anything else unchanged (the type
        check of :func:`load_config` reports it).

    Raises
    ------
    ConfigError
        An unknown key of the fleet form, a count, start or digits out of range, or ids that
        are not ``[A-Za-z0-9._-]+``.
    """
    if not isinstance(duts, dict):
        return duts
    if "count" not in duts or isinstance(duts["count"], dict | None):  # {id: {...}}: a device named count
        return [{"id": k, **(v or {})} for k, v in duts.items()]
    unknown = sorted(set(duts) - set(_FLEET_KEYS))
    if unknown:
        raise ConfigError(source, f"duts.{unknown[0]}", "one of " + ", ".join(_FLEET_KEYS), "an unknown key")
    count = _fleet_int(duts, "count", 0, 1, MAX_FLEET_DUTS, source)
    start = _fleet_int(duts, "start", 1, 0, 10**9, source)
    digits = _fleet_int(duts, "digits", 3, 1, 12, source)
    prefix = duts.get("prefix", "unit-")
    if not isinstance(prefix, str):
        raise ConfigError(source, "duts.prefix", "a string", repr(prefix))
    ids = [f"{prefix}{start + k:0{digits}d}" for k in range(count)]
    if not ID_PATTERN.match(ids[0]):
        raise ConfigError(source, "duts.prefix", "letters, digits, '.', '_' or '-' (device ids)",
                          repr(prefix))
    shared = {k: duts[k] for k in ("up_axis", "reference_to_sensor") if k in duts}
    return [{"id": i, **shared} for i in ids]


def load_config(name_or_path: str | Path, overrides: dict[str, Any] | None = None) -> SimConfig:
    """Load a simulator configuration.

    Parameters
    ----------
    name_or_path
        A built-in profile name (see :func:`builtin_profiles`) or a YAML file, which may
        name a base ``profile``.
    overrides
        Extra keys merged last (e.g. from params.yaml).

    Returns
    -------
    SimConfig

    Raises
    ------
    ConfigError
        Unknown profile, unknown key, wrong type or inconsistent values.
    """
    data = _load_raw(name_or_path)
    if overrides:
        data = deep_merge(data, overrides)
    source = str(name_or_path)
    if "duts" in data:  # {id: {...}} or the fleet form {count: ..., prefix: ...} as well as a list
        data["duts"] = expand_duts(data["duts"], source)
    cfg = from_plain(data, SimConfig, source)
    return _check(cfg, source)


def load_config_from(cfg: SimConfig, overrides: dict[str, Any], source: str = "<config>") -> SimConfig:
    """``cfg`` with ``overrides`` merged over its keys, checked like :func:`load_config`."""
    plain = config_to_dict(cfg)
    if isinstance(overrides.get("duts"), dict):  # a compact form replaces the devices
        plain.pop("duts")
    data = deep_merge(plain, overrides)
    if "duts" in data:
        data["duts"] = expand_duts(data["duts"], source)
    return _check(from_plain(data, SimConfig, source), source)


def config_to_dict(cfg: SimConfig) -> dict[str, Any]:
    """Plain (JSON/YAML-ready) form of a configuration.

    ``reference_format`` and ``continuous`` are left out at their defaults, so that campaigns
    written before the keys existed keep the same bytes.
    """

    def plain(v: Any) -> Any:
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    out = plain(dataclasses.asdict(cfg))
    if out["reference_format"] == DEFAULT_REFERENCE_FORMAT:
        del out["reference_format"]
    if out["continuous"] is None:
        del out["continuous"]
    if out["free_living"] is None:
        del out["free_living"]
    return out
