"""What the report commands show before a report is made: their default output folder,
campaigns, protocols and file layouts.

Apart from the reports themselves (:mod:`~ofbe_data.reports.small_angle`,
:mod:`~ofbe_data.reports.index`), which import NumPy, pandas and Matplotlib, so that
``ofbe-small-angle --help`` and ``ofbe-index --help`` build their parsers from this module alone
(:mod:`ofbe_data.cli`). The report modules import these names from here.
"""

from __future__ import annotations

from pathlib import Path

SMALL_ANGLE_OUT = Path("reports/small_angle")
"""``ofbe-small-angle``'s report folder (:data:`ofbe_data.reports.small_angle.DEFAULT_OUT`)."""

DEFAULT_CAMPAIGNS = ("gravity-aligned", "rotated")
"""The campaigns ``ofbe-index`` indexes unless told others."""
DEFAULT_PROTOCOLS = ("paper-gravity", "paper-rotated", "grouped")
"""The benchmark protocols ``ofbe-index`` indexes unless told others."""
TIMINGS_FORMAT = '{"stages": {"<stage>": <seconds>, ...}}'
"""Layout of ``ofbe-index``'s ``--timings`` file."""
