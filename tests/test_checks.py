"""sprayplan.checks: one check, one message, one exception type for each fault of a point array or a size."""

from __future__ import annotations

import numpy as np
import pytest

from sprayplan.checks import check_count, check_points, check_positive
from sprayplan.errors import ConfigError, DataError, InputError
from sprayplan.ordering import solve_tour
from sprayplan.paths import cloudprep, polyline


def test_points_come_back_as_a_new_float64_array():
    given = [[0, 1, 2], [3, 4, 5]]
    out = check_points(given)
    assert out.dtype == np.float64 and out.shape == (2, 3)
    source = np.arange(6.0).reshape(2, 3)
    copy = check_points(source)
    copy[0, 0] = 99.0
    assert source[0, 0] == 0.0
    assert check_points(np.zeros((0, 3))).shape == (0, 3)


@pytest.mark.parametrize(
    ("points", "kwargs", "got"),
    [
        (np.zeros((4, 2)), {}, "got shape (4, 2)"),
        (np.zeros(3), {}, "got shape (3,)"),
        (np.zeros((2, 3, 1)), {}, "got shape (2, 3, 1)"),
        ([[0, 0, np.nan]], {}, "got NaN or inf"),
        ([[0, 0, np.inf]], {}, "got NaN or inf"),
        ([["a", "b", "c"]], {}, "got something that is not numbers"),
        ([[0, 0, 0], [1, 1]], {}, "got something that is not numbers"),
        (np.zeros((1, 3)), {"min_count": 2}, "got 1 point"),
        (np.zeros((4, 4)), {"dim": (2, 3)}, "got shape (4, 4)"),
    ],
)
def test_each_fault_is_a_data_error_naming_the_argument_and_shape(points, kwargs, got):
    with pytest.raises(DataError) as caught:
        check_points(points, "corners", **kwargs)
    message = str(caught.value)
    assert message.startswith("corners must be an ")
    assert message.endswith(got)
    shape = "(n, 2) or (n, 3)" if kwargs.get("dim") == (2, 3) else "(n, 3)"
    assert shape in message
    assert isinstance(caught.value, InputError) and isinstance(caught.value, ValueError)


def test_dim_and_min_count():
    assert check_points(np.zeros((5, 2)), dim=(2, 3)).shape == (5, 2)
    assert check_points(np.zeros((5, 7)), dim=None).shape == (5, 7)
    assert check_points(np.zeros((2, 3)), min_count=2).shape == (2, 3)
    with pytest.raises(DataError, match=r"\(n, d\)"):
        check_points(np.zeros(4), dim=None)
    with pytest.raises(DataError, match="with at least 3 points"):
        check_points(np.zeros((2, 3)), min_count=3)


def test_an_empty_list_is_zero_points_only_when_asked():
    assert check_points([], dim=(2, 3), empty_list=True).shape == (0, 2)
    with pytest.raises(DataError, match=r"got shape \(0,\)"):
        check_points([])


def test_the_former_copies_now_raise_the_same_error():
    bad = np.zeros((4, 2, 2))
    for call in (
        lambda: solve_tour(bad),
        lambda: cloudprep.remove_outliers(bad),
        lambda: polyline.polyline_length(bad),
    ):
        with pytest.raises(DataError, match=r"points must be an .* array of finite numbers, got shape \(4, 2, 2\)"):
            call()
    # what each accepted is still accepted: tours in the plane and of no points, polylines in space
    assert len(solve_tour(np.zeros((0, 2))).order) == 0
    assert len(solve_tour([]).order) == 0
    assert len(solve_tour(np.zeros((3, 3))).order) == 3
    with pytest.raises(DataError):
        polyline.polyline_length(np.zeros((3, 2)))


def test_positive_and_count():
    assert check_positive(2, "radius_mm") == 2.0 and isinstance(check_positive(2, "radius_mm"), float)
    for bad in (0, -1.0, np.nan, np.inf, "x", None):
        with pytest.raises(ConfigError, match="radius_mm must be a positive number, got "):
            check_positive(bad, "radius_mm")
    assert check_count(3.0, "k", 1) == 3
    for bad in (0, 2.5, True):
        with pytest.raises(ConfigError, match="k must be an integer >= 1"):
            check_count(bad, "k", 1)
