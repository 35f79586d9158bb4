"""Checks of single scene values: each takes a value and returns what is
wrong with it (a text for the error message) or None.  Used by the
schema of :mod:`skfem_rkpm.runs.scene`, which raises :class:`SceneError`.
"""

import math
from dataclasses import dataclass

__all__ = ["SceneError", "COMPONENTS", "HISTORY", "MAX_QUADRATURE"]


class SceneError(ValueError):
    """A scene file is wrong; the message names the key and the line."""


@dataclass(frozen=True)
class Key:
    """One key of the schema: its type, default and meaning."""

    kind: str  # "str", "float", "int", "bool", "list[float]", "list[int]", "list[str]", "any"
    default: object = None
    required: bool = False
    choices: tuple = ()
    doc: str = ""
    check: object = None  # callable value -> error text or None



def _positive(v):
    return None if v > 0 else "must be positive"


def _quadrature(v):
    if v < 1:
        return "must be positive"
    return None if v <= MAX_QUADRATURE else (
        f"must be at most {MAX_QUADRATURE} (the highest Gauss rule for triangles)")


def _non_negative(v):
    return None if v >= 0 else "must not be negative"


def _fraction(v):
    return None if 0.0 < v < 1.0 else "must lie in (0, 1)"


def _poisson(v):
    return None if -1.0 < v < 0.5 else "must lie in (-1, 0.5)"


def _pair(v):
    return None if len(v) == 2 else "needs two values"


def _not_empty(v):
    return None if v else "must name at least one boundary (omit the key for all of them)"


def _triple(v):
    return None if len(v) == 3 else "needs three values [x, y, z]"


def _cell_counts(v):
    if len(v) not in (2, 3):
        return "needs two values [nx, ny] (a box: three, [nx, ny, nz])"
    return None if min(v) >= 1 else "needs at least one cell in each direction"


def _grading(v):
    if len(v) != 2:
        return "needs two values"
    return None if min(v) >= 1 else "ratios must be >= 1 (largest / smallest cell)"


def _is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _xy(v):
    """True if ``v`` is a point [x, y] of two finite numbers."""
    return (isinstance(v, list) and len(v) == 2 and all(_is_number(x) for x in v)
            and all(math.isfinite(x) for x in v))


def _polyline_points(v):
    if isinstance(v, list) and len(v) >= 2 and all(_xy(p) for p in v):
        return None
    return "must be a list of at least two [x, y] points of finite numbers"


def _named_points(v):
    if isinstance(v, dict) and all(
            isinstance(p, list) and len(p) in (2, 3) and all(_is_number(x) for x in p)
            and all(math.isfinite(x) for x in p) for p in v.values()):
        return None
    return ("must be a table of points, {name = [X, Y], ...} (3D: [X, Y, Z]), of finite "
            "numbers")


def _increasing_pair(v):
    if len(v) != 2:
        return "needs two values [min, max]"
    return None if v[1] > v[0] else "needs min < max"


def _friction(v):
    if isinstance(v, str):
        return None if v == "stick" else 'must be a number >= 0 or "stick"'
    if _is_number(v) and math.isinf(v) and v > 0:
        return 'must be finite; use "stick" for no sliding'
    return None if _is_number(v) and v >= 0 else 'must be a number >= 0 or "stick"'


def _segments(v):
    message = "must be a list of [end, cells] pairs with increasing ends and cells >= 1"
    if not isinstance(v, list) or not v:
        return message
    ends = []
    for item in v:
        if not (isinstance(item, list) and len(item) == 2
                and all(_is_number(x) for x in item) and math.isfinite(item[0])
                and isinstance(item[1], int) and item[1] >= 1):
            return message
        ends.append(float(item[0]))
    return None if all(b > a for a, b in zip(ends, ends[1:])) else message


def _history_value(v):
    """A number, or a table [[t, value], ...] with increasing t in [0, 1]."""
    if _is_number(v):
        return math.isfinite(v)
    if not (isinstance(v, list) and v and all(isinstance(row, list) and len(row) == 2
                                              and all(_is_number(x) and math.isfinite(x)
                                                      for x in row) for row in v)):
        return False
    t = [row[0] for row in v]
    return t[0] >= 0 and t[-1] <= 1 and all(b > a for a, b in zip(t, t[1:]))


HISTORY = "a number (reached linearly in the load factor t) or a table [[t, value], ...]"


def _history(v):
    return None if _history_value(v) else f"must be {HISTORY} with increasing t in [0, 1]"


def _vector_history(v):
    message = ("must be a vector [x, y] (3D: [x, y, z]) of numbers (each reached linearly "
               f"in t) or a table {{x = ..., y = ...}} of components, each {HISTORY}")
    if isinstance(v, list):
        return None if len(v) in (2, 3) and all(_is_number(x) and math.isfinite(x)
                                                for x in v) else message
    if isinstance(v, dict) and v:
        for name, value in v.items():
            if name not in COMPONENTS:
                return f"unknown component {name!r}; use x, y or z (r for x)"
            if not _history_value(value):
                return f"component {name}: must be {HISTORY} with increasing t in [0, 1]"
        if len({COMPONENTS[n] for n in v}) != len(v):
            return "names a component twice (r is x)"
        return None
    return message


def _flow_curve(v):
    message = ("must be a list of at least two [plastic strain, stress] points, the "
               "first at plastic strain 0")
    if not (isinstance(v, list) and len(v) >= 2 and all(_xy(p) for p in v)):
        return message
    return None if v[0][0] == 0 else message


def _annulus_radii(v):
    if len(v) != 2:
        return "needs two values [inner, outer]"
    return None if 0 < v[0] < v[1] else "needs 0 < inner < outer"


def _angle_span(v):
    if len(v) != 2:
        return "needs two values [start, end] in degrees"
    return None if 0 < v[1] - v[0] <= 360 else "needs start < end <= start + 360"


COMPONENTS = {"x": 0, "y": 1, "z": 2, "r": 0}

#: highest Gauss rule degree scikit-fem has for triangles
MAX_QUADRATURE = 19
