"""DVC stage ``simulate``: write the default simulated campaigns into raw/.

Reads ``simulate`` from params.yaml; all logic lives in :mod:`ofbe_data.simulator`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import yaml

from ofbe_data.errors import OfbeError
from ofbe_data.simulator import simulate_campaign


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        params = yaml.safe_load(fh)["simulate"]
    try:
        for name, entry in params["campaigns"].items():
            result = simulate_campaign(entry["profile"], Path("raw") / name, seed=entry["seed"],
                                       jobs=params["jobs"], force=True)
            print(f"{result.folder}: {result.sessions} sessions, {result.files} files, "
                  f"{result.bytes / 1e6:.1f} MB")
    except OfbeError as exc:
        print(f"simulate: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
