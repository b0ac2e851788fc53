"""What a generic csv file's banner says about its sensor: the lines before the data often name
the chip and its range (``# ADXL345 on Arduino, range +/-4g, 100 Hz``), which ``ofbe-session
init`` writes as ``model`` and ``range_g`` rather than leaving ``model: unknown`` and a range to
infer from the data.

Only a chip-like name (letters then digits: ADXL345, MPU-6050, BMI160, LSM6DSO, ICM-20948…)
next to nothing else that could be a model counts as a model, and a range only when the text
says so (``range``, ``full scale`` or ``FS`` before ``±N g``); a number alone never does.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

CHIP = re.compile(r"(?<![A-Za-z0-9])((?:(?:ADXL|ADIS|MPU|ICM|BMI|BMA|BMX|MMA|MXC|KX[A-Z]{0,3}|IAM|QMI)"
                  r"-?\d{2,5}|(?:LSM|LIS|IIS|ISM|H3LIS)\d{1,3}[A-Z]{1,4})[A-Z]{0,4}\d{0,3})(?![A-Za-z0-9])",
                  re.IGNORECASE)
"""A MEMS accelerometer or IMU part number."""
RANGE = re.compile(r"(?:range|full[- ]?scale|\bFS\b)\s*[:=]?\s*(?:\+/-|\+-|±)?\s*(\d{1,2}(?:\.\d+)?)\s*g\b",
                   re.IGNORECASE)
"""A stated full-scale range in g."""
RANGES_G = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 30.0, 40.0, 64.0, 100.0, 200.0, 400.0)
"""Full-scale ranges sensors are sold with; a stated range outside these is not taken."""


@dataclass(frozen=True)
class Banner:
    """The sensor facts a banner states, each with the (1-based) line that states it.

    Attributes
    ----------
    model, model_line
        Part number as written (upper case), or None.
    range_g, range_line
        Full-scale range, g, or None.
    """

    model: str | None = None
    model_line: int | None = None
    range_g: float | None = None
    range_line: int | None = None


def read_banner(lines: list[str], stop: int) -> Banner:
    """The chip and range stated by ``lines[:stop]`` (the lines before the data).

    Parameters
    ----------
    lines
        The file's first lines, as text.
    stop
        Index of the first data line.

    Returns
    -------
    Banner
        What the first line naming a chip and the first line stating a range say; a line naming
        two different chips gives no model (which one is the sensor is not said).
    """
    model = range_g = None
    model_line = range_line = None
    for i, line in enumerate(lines[:stop]):
        chips = {m.group(1).upper().replace("-", "") for m in CHIP.finditer(line)}
        if model is None and len(chips) == 1:
            model, model_line = CHIP.search(line).group(1).upper(), i + 1  # type: ignore[union-attr]
        found = RANGE.search(line)
        if range_g is None and found is not None and float(found.group(1)) in RANGES_G:
            range_g, range_line = float(found.group(1)), i + 1
    return Banner(model, model_line, range_g, range_line)
