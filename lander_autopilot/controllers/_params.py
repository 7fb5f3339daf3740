"""Validation of controller parameters: errors name the parameter, the expected and the found shape."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .base import ControllerError


def matrix_param(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float array of exactly ``shape`` (a vector may be given for a 1-row matrix)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ControllerError(f"{name}: expected a numeric array of shape {shape}, got {value!r}") from None
    if a.shape != shape and a.size == int(np.prod(shape)) and (a.ndim == 1 or 1 in shape):
        a = a.reshape(shape)
    if a.shape != shape:
        raise ControllerError(f"{name}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ControllerError(f"{name}: all entries must be finite, got {a.tolist()}")
    return a


def poles_param(name: str, value: object, n: int) -> np.ndarray:
    """``n`` closed-loop poles, all strictly in the left half plane."""
    try:
        p = np.asarray(value, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise ControllerError(f"{name}: expected {n} poles (numbers), got {value!r}") from None
    if p.size != n:
        raise ControllerError(f"{name}: expected {n} poles, got {p.size}: {value!r}")
    if not np.all(np.isfinite(p)) or np.any(p.real >= 0.0):
        raise ControllerError(f"{name}: expected {n} poles, finite with negative real part, got {value!r}")
    return p


def _number_param(name: str, value: object, ok: Callable[[float], bool], expected: str) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]  # any object: float() itself is the check (caught below)
    except (TypeError, ValueError):
        raise ControllerError(f"{name}: expected {expected}, got {value!r}") from None
    if not np.isfinite(v) or not ok(v):
        raise ControllerError(f"{name}: expected {expected}, got {value!r}")
    return v


def positive_param(name: str, value: object) -> float:
    return _number_param(name, value, lambda v: v > 0.0, "a positive number")


def non_negative_param(name: str, value: object) -> float:
    return _number_param(name, value, lambda v: v >= 0.0, "a number >= 0")
