"""From labels to shareable datasets: windows, leak-free splits, the HDF5 + Parquet store.

Windows cut from labelled segments (:mod:`~ofbe_data.dataset.windows`), the protocols' folds
(:mod:`~ofbe_data.dataset.splits`), building a dataset (:mod:`~ofbe_data.dataset.build`),
the store: writing, reading and verifying, exporting (:mod:`~ofbe_data.dataset.store`), the
files other tools read (the signal Parquet files, :mod:`~ofbe_data.dataset.signals`, and
Croissant, :mod:`~ofbe_data.dataset.croissant`), label fidelity against a simulator's truth
(:mod:`~ofbe_data.dataset.fidelity`) and ``ofbe-dataset`` (:mod:`~ofbe_data.cli.dataset`). It may
import :mod:`ofbe_data.core`, :mod:`ofbe_data.io` and :mod:`ofbe_data.labelling`.
"""
