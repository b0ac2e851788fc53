"""``ofbe-train``: OFBENet on every fold (and seed) of a windowed dataset under one protocol
(ofbe_model.ofbenet.training).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.cli import (
    add_jobs,
    add_params,
    add_scheduler,
    add_verbose,
    command,
    fail,
    quiet_libraries,
)
from ofbe_data.core.errors import ConfigError, OfbeError
from ofbe_data.dataset.store import fold_column

PROG = "ofbe-train"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG,
                                description="Train OFBENet on every fold of a windowed dataset under one "
                                            "protocol; write models, histories, curves and a summary.")
    p.add_argument("dataset", help="dataset folder (processed/datasets/<name>)")
    p.add_argument("--protocol", required=True, help="protocol: a fold_<protocol> column of the dataset")
    p.add_argument("--out", default="models", help="models folder (default: models)")
    p.add_argument("--folds", type=int, nargs="+", metavar="K", help="train only these folds (default: all)")
    p.add_argument("--max-epochs", type=int, help="override train.max_epochs")
    p.add_argument("--seeds", type=int, metavar="N",
                   help="train every fold with N seeds (train.seed … train.seed + N − 1; "
                        "overrides train.seeds)")
    add_params(p, "train", "the OFBENet parameters and the number of seeds")
    add_jobs(p, "fits trained at once, each in a single-threaded worker (the models do not depend on it)")
    add_scheduler(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary line")
    add_verbose(p)
    return p


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-train``.

    Returns
    -------
    int
        0 on success, 1 on bad data or a failed fit, 2 on a usage or parameter error.
    """
    args = _parser().parse_args(argv)
    # TensorFlow is imported only now: --help answers at once, and its start-up lines stay quiet
    quiet_libraries(args.verbose)
    from ofbe_model.ofbenet.training import _Usage, read_params, read_seed_count, train

    try:
        params = read_params(args.params, args.max_epochs)
        seeds = read_seed_count(args.params, args.seeds)
        if args.jobs < 1:
            raise ConfigError("command line", "--jobs", "an integer >= 1", str(args.jobs))
        fold_column(args.protocol)
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    dataset = Path(args.dataset)
    if not dataset.is_dir():
        return fail(PROG, f"{dataset}: expected a dataset folder, found no such folder", 2)
    t0 = time.perf_counter()
    try:
        written = train(dataset, args.protocol, args.out, params, args.folds, progress=not args.quiet,
                        seeds=seeds, jobs=args.jobs, scheduler=args.scheduler)
    except _Usage as exc:
        return fail(PROG, str(exc), 2)
    except (OfbeError, OSError) as exc:
        return fail(PROG, str(exc), 1)
    if not args.quiet:
        print(f"{PROG}: trained {args.protocol} on {dataset} in {time.perf_counter() - t0:.0f} s; summaries: "
              f"{', '.join(map(str, written))}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
