"""``rcl_interfaces/ParameterValue`` <-> Python values (typed by the Python value)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any


def parameter_value(v: object) -> Any:
    """``ParameterValue`` of ``v``: bool, int, float, str, or a list of floats (double array)."""
    from rcl_interfaces.msg import ParameterType, ParameterValue

    if isinstance(v, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=v)
    if isinstance(v, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=v)
    if isinstance(v, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=v)
    if isinstance(v, (list, tuple)):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[float(x) for x in v])
    return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=str(v))


def python_value(pv: Any) -> Any:
    """The Python value of a ``ParameterValue`` (None when not set)."""
    from rcl_interfaces.msg import ParameterType as T

    getters: dict[int, Callable[[], Any]] = {
        T.PARAMETER_BOOL: lambda: pv.bool_value,
        T.PARAMETER_INTEGER: lambda: pv.integer_value,
        T.PARAMETER_DOUBLE: lambda: pv.double_value,
        T.PARAMETER_STRING: lambda: pv.string_value,
        T.PARAMETER_DOUBLE_ARRAY: lambda: list(pv.double_array_value),
        T.PARAMETER_INTEGER_ARRAY: lambda: list(pv.integer_array_value),
        T.PARAMETER_BOOL_ARRAY: lambda: list(pv.bool_array_value),
        T.PARAMETER_STRING_ARRAY: lambda: list(pv.string_array_value),
    }
    get = getters.get(pv.type)
    return None if get is None else get()
