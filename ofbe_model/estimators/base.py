"""The one estimator interface, and the registry of estimators by name.

Every bias estimator follows scikit-learn's conventions: parameters are keyword arguments
of ``__init__`` stored unchanged under the same names, all work happens in :meth:`fit`, and
learned values end in ``_``. A window is (T, 3) specific force in m/s², sensor frame; a
batch is (N, T, 3). ``meta`` is a pandas DataFrame with one row per window carrying at least
``device`` (str) and ``g_local`` (m/s²); dataset windows also carry ``fs_hz``,
``power_cycle``, the session identity and so on (docs/datasets.md). Estimators must not read
label columns (``bias_*``, ``offset_*``, ``gravity_*``, ``roll_deg``, ``pitch_deg``) from
``meta`` in :meth:`predict`.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar, TypeVar

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError

#: Columns every ``meta`` frame must have.
META_REQUIRED = ("device", "g_local")


class EstimatorError(OfbeError):
    """An estimator used wrongly: unknown name, predict before fit, bad shapes or meta."""


class Estimator:
    """Base class of every bias estimator.

    Class attributes
    ----------------
    name
        Registry name (``level-mean``, ``ls-trf``...).
    needs_fit
        Whether :meth:`fit` learns anything (physics-only estimators return ``self``).
    order
        Where the estimator comes in :func:`registered_names` (the benchmark's default rows):
        ascending, ties by name. The built-in ones take 10–60 and the oracle :data:`LAST`; a new
        estimator left at the default comes after them and before the oracle.
    """

    name: ClassVar[str] = ""
    needs_fit: ClassVar[bool] = False
    order: ClassVar[int] = 100

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> Estimator:
        """Learn from training windows.

        Parameters
        ----------
        windows
            (N, T, 3) m/s².
        labels
            (N, 3) apparent-bias labels, m/s².
        meta
            N rows (see the module docstring).

        Returns
        -------
        self
        """
        check_inputs(windows, meta, labels)
        return self

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s²."""
        raise NotImplementedError

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior standard deviations, (N, 3) m/s², for estimators that have them.

        Raises
        ------
        NotImplementedError
            The estimator gives no uncertainty.
        """
        raise NotImplementedError(f"{self.name or type(self).__name__} gives no standard deviation")

    @property
    def has_std(self) -> bool:
        """Whether :meth:`predict_std` is implemented."""
        return type(self).predict_std is not Estimator.predict_std

    def get_params(self) -> dict[str, Any]:
        """The ``__init__`` parameters and their current values (scikit-learn style)."""
        sig = inspect.signature(type(self).__init__)
        skip = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
        return {p: getattr(self, p) for p, spec in sig.parameters.items()
                if p != "self" and spec.kind not in skip}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"


def check_inputs(windows: np.ndarray, meta: pd.DataFrame, labels: np.ndarray | None = None) -> None:
    """Check shapes and required meta columns.

    Raises
    ------
    EstimatorError
        Windows not (N, T, 3), meta or labels of another length, a missing meta column.
    """
    w = np.asarray(windows)
    if w.ndim != 3 or w.shape[2] != 3:
        raise EstimatorError(f"windows: expected an array of shape (N, T, 3), found shape {w.shape}")
    if len(meta) != w.shape[0]:
        raise EstimatorError(f"meta: expected {w.shape[0]} rows (one per window), found {len(meta)}")
    missing = [c for c in META_REQUIRED if c not in meta.columns]
    if missing:
        raise EstimatorError(f"meta: expected columns {', '.join(META_REQUIRED)}, "
                             f"found no {', '.join(missing)}")
    if labels is not None and np.asarray(labels).shape != (w.shape[0], 3):
        raise EstimatorError(f"labels: expected shape ({w.shape[0]}, 3), found {np.asarray(labels).shape}")


LAST = 1000
"""The :attr:`Estimator.order` of the oracle, which reads the simulator's truth: listed last."""

E = TypeVar("E", bound=type[Estimator])
_REGISTRY: dict[str, type[Estimator] | str] = {}
"""Name → the estimator class, or the module that defines it (registered lazily)."""
_ORDER: dict[str, int] = {}
"""Name → its :attr:`Estimator.order`."""


def register(cls: E) -> E:
    """Class decorator: make an estimator available by its ``name`` (in place of a lazy entry)."""
    if not cls.name:
        raise EstimatorError(f"{cls.__name__}: expected a non-empty class attribute 'name'")
    _REGISTRY[cls.name] = cls
    _ORDER[cls.name] = cls.order
    return cls


def register_lazy(name: str, module: str, order: int = Estimator.order) -> None:
    """Make estimator ``name`` available before its module is imported: ``make_estimator(name)``
    imports ``module`` (dotted), whose ``@register`` then registers the class (whose ``order``
    should be ``order``). For an estimator whose module is heavy to import (OFBENet: TensorFlow).
    No effect when ``name`` is registered."""
    if name not in _REGISTRY:
        _REGISTRY[name] = module
        _ORDER[name] = order


def unregister(name: str) -> None:
    """Remove an estimator (a plug-in's, or a test's toy estimator); no error when absent."""
    _REGISTRY.pop(name, None)
    _ORDER.pop(name, None)


def estimator_names() -> tuple[str, ...]:
    """Registered names, sorted."""
    return tuple(sorted(_REGISTRY))


def registered_names() -> tuple[str, ...]:
    """Registered names by :attr:`Estimator.order`, ties by name (the benchmark's default rows)."""
    return tuple(sorted(_REGISTRY, key=lambda n: (_ORDER[n], n)))


def make_estimator(name: str, **params: Any) -> Estimator:
    """A new estimator by registry name.

    Raises
    ------
    EstimatorError
        Unknown name (the message lists the known ones) or unknown parameters.
    """
    entry = _REGISTRY.get(name)
    if entry is None:
        raise EstimatorError(f"estimator: expected one of {', '.join(sorted(_REGISTRY))}, found {name!r}")
    if isinstance(entry, str):
        import importlib

        importlib.import_module(entry)
        entry = _REGISTRY[name]
        if isinstance(entry, str):
            raise EstimatorError(f"estimator {name}: expected module {entry} to register it (@register), "
                                 "found no estimator of that name in it")
    try:
        return entry(**params)
    except TypeError as exc:
        raise EstimatorError(f"estimator {name}: {exc}") from None
