"""DVC stage ``small_angle``: the levelled-calibration gravity-leak report.

Reads ``small_angle`` from params.yaml; all logic lives in :mod:`ofbe_data.reports.small_angle`.
"""

from __future__ import annotations

import sys

from ofbe_data.cli.small_angle import main as small_angle_main
from ofbe_data.io.pipeline_params import load_params, timed


def main(params_file: str = "params.yaml") -> int:
    p = load_params(params_file)["small_angle"]
    return small_angle_main(["--out", "reports/small_angle", "--range-deg", str(p["range_deg"]),
                             "--step-deg", str(p["step_deg"]), "--limit-mg", str(p["limit_mg"])])


if __name__ == "__main__":
    with timed("small_angle"):
        code = main()
    sys.exit(code)
