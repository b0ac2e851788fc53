"""DVC stage ``index``: reports/index.md, linking every table and figure of the run.

Reads ``profile``, ``label_run`` (campaigns) and ``benchmark_run`` (protocols) from
params.yaml and the stage times the other entries recorded in .ofbe/timings.json; all
logic lives in :mod:`ofbe_data.reports.index`.
"""

from __future__ import annotations

import sys

from ofbe_data.cli.index import main as index_main
from ofbe_data.io.pipeline_params import TIMINGS_FILE, load_params


def main(params_file: str = "params.yaml") -> int:
    params = load_params(params_file)
    return index_main(["--out", "reports/index.md", "--profile", str(params.get("profile", "paper")),
                       "--campaigns", *params["label_run"]["campaigns"],
                       "--protocols", *params["benchmark_run"]["protocols"],
                       "--timings", str(TIMINGS_FILE)])


if __name__ == "__main__":
    sys.exit(main())
