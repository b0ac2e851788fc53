"""DVC stage ``simulate``: write the default simulated campaigns into raw/.

Reads ``simulate`` (campaigns, worker processes, an optional ``scheduler``) from params.yaml
(with its profile applied,
:mod:`ofbe_data.io.pipeline_params`); all logic lives in :mod:`ofbe_data.simulator`. Writes the
per-file SHA-256 list ``checksums/simulate.sha256``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ofbe_data.core.checksums import write_sha256_list
from ofbe_data.core.errors import OfbeError
from ofbe_data.io.pipeline_params import load_params, timed
from ofbe_data.simulator import load_config, simulate_campaign

CHECKSUMS = Path("checksums") / "simulate.sha256"
"""Per-file SHA-256 list of raw/ (committed beside dvc.lock; :mod:`ofbe_data.core.checksums`)."""


def main(params_file: str = "params.yaml") -> int:
    try:
        params = load_params(params_file)["simulate"]
        for name, entry in params["campaigns"].items():
            config = load_config(entry["profile"], entry.get("overrides"))
            result = simulate_campaign(config, Path("raw") / name, seed=entry["seed"],
                                       jobs=params["jobs"], force=True,
                                       scheduler=str(params.get("scheduler", "processes")))
            print(f"{result.folder}: {result.sessions} sessions, {result.files} files, "
                  f"{result.bytes / 1e6:.1f} MB")
        write_sha256_list(CHECKSUMS, [Path("raw") / name for name in params["campaigns"]])
    except OfbeError as exc:
        print(f"simulate: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    with timed("simulate"):
        code = main()
    sys.exit(code)
