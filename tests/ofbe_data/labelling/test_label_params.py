"""Labelling parameters out of range are parameter errors naming the key, not internal errors later."""

from __future__ import annotations

import pytest

from ofbe_data.core.errors import ConfigError
from ofbe_data.labelling.labels import label_params_from


@pytest.mark.parametrize("value", [0, 0.5, -3])
def test_a_condition_bound_below_one_is_refused(value: float) -> None:
    with pytest.raises(ConfigError) as info:
        label_params_from({"multi_position_max_condition": value}, "params.yaml")
    assert str(info.value) == (f"params.yaml: label.multi_position_max_condition: expected a number ≥ 1 (a "
                               f"condition number), found {float(value)}")


def test_a_condition_bound_of_one_or_more_is_taken() -> None:
    assert label_params_from({"multi_position_max_condition": 1}, "p").multi_position_max_condition == 1
    assert label_params_from({}, "p").multi_position_max_condition == 1000.0


def test_a_condition_bound_that_is_not_a_number_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"max_condition: expected a finite number, found nan"):
        label_params_from({"multi_position_max_condition": float("nan")}, "params.yaml")
