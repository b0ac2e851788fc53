"""The ``free_living`` section of a simulator configuration (``kind: free-living``).

A free-living campaign is N files (``sessions``), each one wearable device worn by one person
for ``days`` days: the data that free-living calibration (``ofbe-autocal``, docs/free-living.md)
works on. :mod:`ofbe_data.simulator.wear` draws what the wearer does and
:mod:`ofbe_data.simulator.freeliving` what the device records; docs/sensor-model.md, "Free-living
recordings", describes both. The device's scale, non-orthogonality and offset spreads come from
``dut_model`` (``scale_sigma``, ``cross_axis_sigma_deg``, ``offset_sigma_mg``); its other keys (the
bench logger's clock, serial link, drift and turn-on spread) and ``duts``, ``tilts``, ``taps``,
``recordings_per_session`` and ``stationary_s`` do not apply.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ofbe_data.core.errors import ConfigError

Vec3 = tuple[float, float, float]

FREE_LIVING = "free-living"
"""The configuration ``kind`` of free-living campaigns."""
OUTPUTS = ("epochs", "raw", "both")
"""What a free-living campaign writes: epoch csv files, raw sample csv sessions, or both."""
PLACEMENTS = ("wrist", "hip")
"""Where the device is worn."""
MAX_DAYS = 31.0
"""Longest wear per file, days."""
SCENARIOS = ("no-still", "poor-coverage", "idle-sleep", "already-calibrated")
"""Files that test a calibration's QC outcomes, written after the ordinary ones in this order:

- ``no-still``: the device never rests: worn day and night, never taken off, with at least
  :data:`~ofbe_data.simulator.wear.NO_STILL_MOTION_G` of motion in every epoch (a tremor that
  persists, a vehicle), so no epoch's standard deviation falls below GGIR's 13 mg;
- ``poor-coverage``: a hip device worn day and night and never taken off: its −x axis (upside
  down) never points up;
- ``idle-sleep``: ActiGraph's idle-sleep mode on (``idle_sleep``);
- ``already-calibrated``: the file holds readings already calibrated (by the maker, or an earlier
  run): A = I in the convention of a still-epoch calibration (a reading of 1 at rest, local
  gravity), no offset, no temperature slope; a calibration has nothing to remove."""
MAX_SAMPLES_PER_EPOCH = 6000
"""Most raw samples in one epoch (``epoch_s · rate_hz``): 60 s at 100 Hz. Epoch statistics of raw
samples are summed in 64-bit integers, exact up to this many samples."""


@dataclass(frozen=True)
class FreeLivingConfig:
    """What a free-living campaign simulates and writes.

    Attributes
    ----------
    placement
        ``wrist`` (a watch-style device on the left wrist) or ``hip`` (a clip on the right hip):
        which posture clusters the still epochs' gravity directions come from.
    days
        Wear per file, days (a fraction for a few hours).
    output
        ``epochs`` (one epoch csv per file, GGIR's ``spheredata`` layout), ``raw`` (one session
        folder per file with a sample csv and its manifest) or ``both`` (the epochs then computed
        from the raw samples).
    rate_hz
        Sample rate of the raw samples, Hz; the epoch writer draws each epoch's statistics as of
        ``epoch_s · rate_hz`` samples.
    epoch_s
        Epoch length, s (GGIR's 10 s).
    noise_density_ug
        White-noise density per axis, µg/√Hz (ADXL345 datasheet: 290, 290, 430); the noise of one
        sample is this times √(rate_hz / 2), its bandwidth being half the rate.
    temp_coeff_sigma_mg_per_c
        Spread of the offset's temperature coefficient per axis, mg/°C (ADXL345 datasheet's typical
        ±0.8, ±0.8, ±4.5 mg/°C taken as one standard deviation).
    temp_ref_c
        Temperature at which the truth's offset is the zero-g reading, °C (the datasheet's 25 °C).
    idle_sleep
        ActiGraph's idle-sleep mode: after an epoch at rest the device repeats its last sample
        exactly until it moves again.
    nonwear_per_day
        Mean number of non-wear periods (device on a table, 10–120 min) per waking day.
    nonwear_night_prob
        Probability that the device spends a night on the table instead of on the sleeper.
    scenarios
        Files of each of :data:`SCENARIOS` (name → count), written after the ordinary files and
        counted in ``sessions``.
    """

    placement: str = "wrist"
    days: float = 7.0
    output: str = "epochs"
    rate_hz: float = 30.0
    epoch_s: float = 10.0
    noise_density_ug: Vec3 = (290.0, 290.0, 430.0)
    temp_coeff_sigma_mg_per_c: Vec3 = (0.8, 0.8, 4.5)
    temp_ref_c: float = 25.0
    idle_sleep: bool = False
    nonwear_per_day: float = 1.0
    nonwear_night_prob: float = 0.1
    scenarios: dict[str, int] = field(default_factory=dict)

    @property
    def samples_per_epoch(self) -> int:
        """Raw samples in one epoch, ``epoch_s · rate_hz`` (an integer, checked on loading)."""
        return int(round(self.epoch_s * self.rate_hz))

    @property
    def n_epochs(self) -> int:
        """Epochs per file: ``days`` rounded to whole epochs (at least one)."""
        return max(1, int(round(self.days * 86400.0 / self.epoch_s)))


def check_free_living(fl: FreeLivingConfig, source: str) -> None:
    """Semantic checks of the ``free_living`` section that types alone do not catch.

    Parameters
    ----------
    fl
        The section.
    source
        Configuration file or profile, named in errors.

    Raises
    ------
    ConfigError
        A value out of its range, naming the key, what is allowed and what was found.
    """
    key = "free_living."
    if fl.placement not in PLACEMENTS:
        raise ConfigError(source, key + "placement", "one of " + ", ".join(PLACEMENTS), repr(fl.placement))
    if fl.output not in OUTPUTS:
        raise ConfigError(source, key + "output", "one of " + ", ".join(OUTPUTS), repr(fl.output))
    if not (math.isfinite(fl.days) and 0.0 < fl.days <= MAX_DAYS):
        raise ConfigError(source, key + "days", f"0 < days <= {MAX_DAYS:g}", repr(fl.days))
    if not (math.isfinite(fl.epoch_s) and fl.epoch_s >= 1.0):
        raise ConfigError(source, key + "epoch_s", "an epoch of at least 1 s", repr(fl.epoch_s))
    if not (math.isfinite(fl.rate_hz) and 0.0 < fl.rate_hz <= 1000.0):
        raise ConfigError(source, key + "rate_hz", "0 < rate_hz <= 1000", repr(fl.rate_hz))
    per_epoch = fl.epoch_s * fl.rate_hz
    if abs(per_epoch - round(per_epoch)) > 1e-9 or not 2 <= round(per_epoch) <= MAX_SAMPLES_PER_EPOCH:
        raise ConfigError(source, key + "rate_hz", f"epoch_s × rate_hz a whole number of samples in "
                          f"2..{MAX_SAMPLES_PER_EPOCH}",
                          f"{fl.epoch_s:g} s × {fl.rate_hz:g} Hz = {per_epoch:g}")
    for name in ("noise_density_ug", "temp_coeff_sigma_mg_per_c"):
        values = getattr(fl, name)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise ConfigError(source, key + name, "three finite values >= 0", repr(list(values)))
    if not (math.isfinite(fl.temp_ref_c) and -40.0 <= fl.temp_ref_c <= 85.0):
        raise ConfigError(source, key + "temp_ref_c", "a temperature in -40..85 °C", repr(fl.temp_ref_c))
    if not (math.isfinite(fl.nonwear_per_day) and 0.0 <= fl.nonwear_per_day <= 10.0):
        raise ConfigError(source, key + "nonwear_per_day", "a mean count in 0..10", repr(fl.nonwear_per_day))
    if not 0.0 <= fl.nonwear_night_prob <= 1.0:
        raise ConfigError(source, key + "nonwear_night_prob", "a probability in [0, 1]",
                          repr(fl.nonwear_night_prob))
    for name, count in fl.scenarios.items():
        if name not in SCENARIOS:
            raise ConfigError(source, key + "scenarios", "scenario names among " + ", ".join(SCENARIOS),
                              repr(name))
        if not (isinstance(count, int) and count >= 0):
            raise ConfigError(source, f"{key}scenarios.{name}", "a number of files >= 0", repr(count))


def scenario_of(fl: FreeLivingConfig, sessions: int, index: int, source: str = "<config>") -> str | None:
    """The scenario of file ``index`` (0-based) of ``sessions``: None for an ordinary file.

    The last ``sum(fl.scenarios.values())`` files are the scenarios' files, in the order of
    :data:`SCENARIOS`.

    Raises
    ------
    ConfigError
        The scenarios ask for more files than ``sessions``.
    """
    counts = [(name, fl.scenarios.get(name, 0)) for name in SCENARIOS]
    total = sum(c for _, c in counts)
    if total > sessions:
        raise ConfigError(source, "free_living.scenarios",
                          f"at most sessions = {sessions} files in all (counts of 0 for none)", f"{total}")
    k = index - (sessions - total)
    if k < 0:
        return None
    for name, count in counts:
        if k < count:
            return name
        k -= count
    raise IndexError(f"file index {index} out of range for {sessions} files")
