"""``ofbe-dataset``: build a campaign's windowed dataset, verify one, or export it for sharing.

Subcommands::

    ofbe-dataset build processed/labels/<campaign> --raw raw/<campaign> [--out processed/datasets/<name>]
    ofbe-dataset verify processed/datasets/<name>
    ofbe-dataset export processed/datasets/<name> --out DIR [--title ... --licence ... --author ...]

Exit status: 0 on success, 1 when the data are bad (a changed raw file, a checksum that does
not match, a protocol that cannot be applied), 2 on a usage or parameter error. Every
message is one line naming the file.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.cli import add_jobs, add_params, add_scheduler, command, fail, io_failure, with_examples
from ofbe_data.core.errors import ConfigError, OfbeError

PROG = "ofbe-dataset"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ofbe-dataset",
                                description="Windowed datasets with leakage-free folds, as HDF5 + Parquet "
                                            "with a Frictionless data package, a Croissant description, a "
                                            "card (Hugging Face configs, one per protocol) and checksums.")
    sub = p.add_subparsers(dest="command", required=True)
    build_help = "cut a labelled campaign into windows and assign folds"
    b = sub.add_parser("build", help=build_help, description=build_help[0].upper() + build_help[1:] + ".")
    b.add_argument("labels", help="the campaign's label folder (processed/labels/<campaign>)")
    b.add_argument("--raw", required=True, help="the raw campaign folder the labels were made from")
    b.add_argument("--out", help="dataset folder (default: processed/datasets/<campaign>)")
    b.add_argument("--name", help="dataset name (default: the campaign)")
    add_params(b, "dataset", "windowing, folds and protocols")
    b.add_argument("--window-length", type=int, help="override dataset.window_length (samples)")
    b.add_argument("--stride", type=int, help="override dataset.stride (samples)")
    b.add_argument("--shard-windows", type=int,
                   help="override dataset.shard_windows: above this many windows, write shard files of "
                        "this many (windows-00000.h5, ...) instead of one windows.h5")
    b.add_argument("--truth", help="the simulator's truth folder (default: the raw campaign's own, when "
                                   "present): the card then states the label fidelity")
    add_jobs(b, "worker processes reading raw files")
    add_scheduler(b)
    b.add_argument("--force", action="store_true", help="replace an existing dataset folder")
    b.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    verify_help = ("check a dataset's checksums, schema version and consistency, reading every sample of "
                   "the HDF5 and signal files")
    v = sub.add_parser("verify", help=verify_help, description=verify_help[0].upper() + verify_help[1:] + ".")
    v.add_argument("path", help="dataset folder (a built one, or an exported copy)")
    export_help = "write a verified, self-describing copy for sharing"
    e = sub.add_parser("export", help=export_help, description=export_help[0].upper() + export_help[1:] + ".")
    e.add_argument("path", help="dataset folder")
    e.add_argument("--out", required=True, help="new folder")
    e.add_argument("--title", help="the dataset's title on its card (default: the title it has)")
    e.add_argument("--licence", help="SPDX licence id of the data, e.g. CC-BY-4.0")
    e.add_argument("--author", action="append", help="author (repeat for several)")
    e.add_argument("--version", help="dataset version")
    e.add_argument("--force", action="store_true", help="replace an existing --out")
    with_examples(b, "ofbe-dataset build processed/labels/rotated --raw raw/rotated "
                     "--out mine/datasets/rotated --jobs 2")
    with_examples(v, "ofbe-dataset verify processed/datasets/rotated")
    with_examples(e, "ofbe-dataset export processed/datasets/rotated --out share/rotated-v1 "
                     "--licence CC-BY-4.0 --author 'A. Lab'")
    return with_examples(p, "ofbe-dataset build processed/labels/rotated --raw raw/rotated --jobs 2",
                         "ofbe-dataset verify processed/datasets/rotated",
                         "ofbe-dataset export processed/datasets/rotated --out share/rotated-v1 "
                         "--licence CC-BY-4.0")


def _build(args: argparse.Namespace) -> int:
    from ofbe_data.dataset.build import build_dataset, dataset_params_from
    from ofbe_data.dataset.fidelity import truth_dir_of
    from ofbe_data.io.typedconfig import read_section

    try:
        data = dict(read_section(args.params, "dataset")) if args.params else {}
        if args.window_length is not None:
            data["window_length"] = args.window_length
        if args.stride is not None:
            data["stride"] = args.stride
        if args.shard_windows is not None:
            data["shard_windows"] = args.shard_windows
        params = dataset_params_from(data, args.params or "command line")
        if args.jobs < 1:
            raise ConfigError("command line", "--jobs", "an integer ≥ 1", str(args.jobs))
        labels, raw = Path(args.labels), Path(args.raw)
        for path, what in ((labels, "label folder"), (raw, "raw campaign folder")):
            if not path.is_dir():
                return fail(PROG, f"{path}: expected a {what}, found no such folder", 2)
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    truth = Path(args.truth) if args.truth else truth_dir_of(raw)
    if truth is not None and not truth.is_dir():
        return fail(PROG, f"{truth}: expected the simulator's truth folder, found no such folder", 2)
    out = Path(args.out) if args.out else Path("processed/datasets") / (args.name or labels.name)
    try:
        result = build_dataset(labels, raw, out, params, name=args.name,
                               truth_dir=truth,
                               jobs=min(args.jobs, os.cpu_count() or 1), force=args.force,
                               progress=not args.quiet, scheduler=args.scheduler)
    except OfbeError as exc:
        return fail(PROG, str(exc), 1)
    except OSError as exc:
        return io_failure(PROG, exc, out, "the dataset could not be written")
    if not args.quiet:
        print(f"ofbe-dataset: {result.n_windows} windows from {result.n_recordings} recordings "
              f"({len(result.excluded)} too short), protocols {', '.join(result.protocols)} -> {result.path}",
              file=sys.stderr)
    return 0


def _signal_text(signals: Sequence[str]) -> str:
    return f"{signals[0]} holds" if len(signals) == 1 else f"the {len(signals)} signal files hold"


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-dataset``: 0 done, 1 bad data, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-dataset build|verify|export`` on its parsed arguments; the dataset modules are
    imported here, after parsing (docs/architecture.md, "Command lines")."""
    if args.command == "build":
        return _build(args)
    from ofbe_data.dataset.export import export_dataset
    from ofbe_data.dataset.reader import verify_dataset

    try:
        if args.command == "verify":
            s = verify_dataset(args.path)
            print(f"ofbe-dataset: {args.path}: OK — {s['name']} ({s['schema_version']}): {s['n_windows']} "
                  f"windows of {s['window_length']} samples from {s['n_recordings']} recordings of "
                  f"{s['n_devices']} devices; protocols {', '.join(s['protocols'])}; "
                  f"{len(s['files'])} files match their SHA-256 sums; every HDF5 chunk read"
                  + (f"; {_signal_text(s['signals'])} the same samples bit for bit" if s["signals"] else ""))
            return 0
        dest = export_dataset(args.path, args.out, title=args.title, licence=args.licence,
                              authors=tuple(args.author) if args.author else None, version=args.version,
                              force=args.force)
        print(f"ofbe-dataset: exported {args.path} -> {dest}", file=sys.stderr)
        return 0
    except OfbeError as exc:
        return fail(PROG, str(exc), 1)
    except OSError as exc:
        return io_failure(PROG, exc, args.out or args.path, "the export could not be written")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
