"""The model package's formats of ``ofbe-export``: ``tflite`` (OFBENet as TensorFlow Lite) and
``c-header`` (the gravity-prior as a C header), each a
:class:`~ofbe_data.calibration.registry.Format` whose SOURCE is a model file.

The command lives in the data package (:mod:`ofbe_data.cli.export`), which never imports this
package: pyproject.toml registers :data:`TFLITE` and :data:`C_HEADER` in the entry-point group
``ofbe.export_formats``, loaded when the command builds its parser. This module imports only
what the parser needs (the registry's :class:`~ofbe_data.calibration.registry.Format`); NumPy,
the datasets, TensorFlow and the deploy modules load in a format's handler, when it runs.
"""

from __future__ import annotations

import argparse
import re
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from ofbe_data.calibration.registry import Format

if TYPE_CHECKING:
    import numpy as np

    from ofbe_data.calibration.output import ExportFile

__all__ = ["C_HEADER", "TFLITE"]


def _training_windows(args: argparse.Namespace) -> tuple[np.ndarray, str]:
    """The windows a model was trained on, (N, T, 3) m/s², and a description of them; without
    ``--dataset``, the dataset the model card beside SOURCE names (:func:`card_dataset`)."""
    import numpy as np

    from ofbe_data.calibration.output import ExportUsageError

    what = ""
    selected = None
    if args.dataset is None:
        from ofbe_model.deploy.final import ModelCardError, card_dataset, card_selected_devices

        try:
            args.dataset, _ = card_dataset(args.source)  # its hash: check_card_dataset below
        except ModelCardError as exc:
            raise ExportUsageError(f"{args.format} needs --dataset DIR, the dataset the model was trained on "
                                   f"(its training windows are the int8 representative set): {exc}") from None
        what = " (the model card's training data)"
        selected = card_selected_devices(args.source) if args.device is None else None
    from ofbe_data import load_dataset
    from ofbe_model.deploy.tflite import check_card_dataset

    check_card_dataset(args.source, args.dataset)  # a card that names other training data: refused
    data = load_dataset(args.dataset)
    keep = np.ones(len(data.meta), dtype=bool)
    what = f"{args.dataset}{what}"
    if selected is not None:  # a per-device model: its own device's windows only, as the card says
        keep &= data.meta["device"].isin(selected).to_numpy()
        what += f", device {', '.join(selected)}"
    if args.device is not None:
        keep &= (data.meta["device"] == args.device).to_numpy()
        what += f", device {args.device}"
    if args.protocol is not None:
        column = f"fold_{args.protocol}"
        if column not in data.meta.columns:
            known = ", ".join(c[5:] for c in data.meta.columns if c.startswith("fold_"))
            raise ExportUsageError(f"--protocol {args.protocol}: {args.dataset} has no {column} column "
                                   f"(protocols: {known})")
        if args.fold is None:
            raise ExportUsageError("--protocol needs --fold K: the fold whose training windows are meant")
        keep &= (data.meta[column] != args.fold).to_numpy()
        what += f", training windows of {args.protocol} fold {args.fold}"
    else:
        what += ", all windows (a model trained on all of them)"
    if not keep.any():
        raise ExportUsageError(f"{what}: no window left to quantise with")
    return np.asarray(data.X[keep]), what


def _tflite(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.output import ExportFile
    from ofbe_model.deploy.tflite import export_tflite

    windows, what = _training_windows(args)
    with tempfile.TemporaryDirectory(prefix=".ofbe-export-") as tmp:
        sidecar = export_tflite(args.source, tmp, windows, name=args.source.stem, source=what)
        return [ExportFile(name, (Path(tmp) / name).read_bytes()) for name in sidecar["files"].values()]


def _c_header(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_data.calibration.output import ExportFile
    from ofbe_model.deploy.c_header import export_c_header

    name = re.sub(r"[^A-Za-z0-9_]", "_", args.source.stem) or "gravity_prior"
    with tempfile.TemporaryDirectory(prefix=".ofbe-export-") as tmp:
        path = export_c_header(args.source, Path(tmp) / f"{name}.h", name=name)
        return [ExportFile(path.name, path.read_bytes())]


def _tflite_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dataset", type=Path, help="the dataset the model was trained on (when left out: the "
                                                "one model_card.json beside SOURCE names)")
    p.add_argument("--protocol", help="with --fold, only that fold's training windows")
    p.add_argument("--fold", type=int, help="the fold of --protocol the model was trained for")
    p.add_argument("--device", help="only this device's windows (a per-device model)")


TFLITE = Format(_tflite, "OFBENet (SOURCE: a .keras) as float32 and int8 TensorFlow Lite with a JSON "
                         "sidecar of the scaling; --dataset (default: the model card's)",
                _tflite_options,
                ("ofbe-export tflite models/rotated/sparkfun-1/final.keras --out mine/fw/",),
                reads_raw=False)
"""``ofbe-export tflite``: a ``.keras`` OFBENet as float32 and int8 TensorFlow Lite."""

C_HEADER = Format(_c_header, "the gravity-prior (SOURCE: its .json) as a self-contained C header with a "
                             "reference C function",
                  examples=("ofbe-export c-header models/rotated/sparkfun-1/gravity-prior.json "
                            "--out mine/fw/",),
                  reads_raw=False)
"""``ofbe-export c-header``: the gravity-prior estimator as a self-contained C header."""
