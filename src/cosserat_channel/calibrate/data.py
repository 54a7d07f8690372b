"""Measurements to calibrate against: one table, one measurement per row, read and checked.

A table has the columns ``quantity`` (an output of :data:`cosserat_channel.outputs.OUTPUTS`,
or a profile of :data:`~cosserat_channel.outputs.PROFILES` at the row's ``xi``), ``value``,
``std_error`` (its standard error, > 0), ``xi`` for profile rows, and any of the inputs that vary
between rows: the model's parameters (``eps``, ``L``, ``K``, ``A``, ``N``), the material's
(``d_p``, ``rho_p``, ``phi``, ...) and the engineers' inputs (``W``, ``delta_w``). An empty cell
(NaN) in an input column means "not given for this row": the fit's fixed or free value holds
there.

Pure Python plus numpy: reading and checking a table imports neither numba nor scipy.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .. import outputs as out_
from ..parameters import MATERIAL, PARAMETERS, PHYSICAL, ParameterError, parse_number

__all__ = ["DataError", "Measurements", "read_data", "INPUTS", "quantities", "profile_quantities",
           "CSV_EXAMPLE"]

QUANTITY, VALUE, STD_ERROR, XI = "quantity", "value", "std_error", "xi"
REQUIRED = (QUANTITY, VALUE, STD_ERROR)

# What a row, or the fit, may set: the point's parameters, the material and the engineers'
# inputs that give eps (W with d_p) and N (delta_w with phi).
INPUTS = {**PARAMETERS, **MATERIAL, **PHYSICAL}

# xi_stop exists only where a point has no solution: nothing to fit.
_NOT_FITTABLE = ("xi_stop",)

CSV_EXAMPLE = """\
# a velocity profile at one channel width and the shear-layer thickness at two more
quantity,value,std_error,xi,eps
u_over_u0,1.000,0.005,0.2,1/30
u_over_u0,0.790,0.005,0.8,1/30
Delta,18.6,0.5,,0.01
Delta,10.3,0.5,,1/30
"""

def quantities() -> tuple[str, ...]:
    """The scalar quantities a row may measure (read from the registry at each call)."""
    return tuple(n for n in out_.OUTPUTS if n not in _NOT_FITTABLE)


def profile_quantities() -> tuple[str, ...]:
    """The profile quantities a row may measure at its ``xi``."""
    return tuple(out_.PROFILES)


class DataError(ParameterError):
    """A measurement table that cannot be used; the message names the row and the column."""


@dataclass
class Measurements:
    """A checked measurement table.

    Attributes
    ----------
    quantity : numpy.ndarray of str
        What each row measures.
    value, std_error : numpy.ndarray
        The measured value and its standard error (> 0).
    xi : numpy.ndarray
        Where a profile row measures (NaN for scalar rows).
    columns : dict
        The input columns (names of :data:`INPUTS`), float64 with NaN where a row gives none.
    source : str
        Where the table came from (a path, ``"data"``), for messages.
    lines : numpy.ndarray of int or None
        For a CSV file, the line of each row (messages name it).
    """

    quantity: np.ndarray
    value: np.ndarray
    std_error: np.ndarray
    xi: np.ndarray
    columns: dict
    source: str = "data"
    lines: np.ndarray | None = None

    def __len__(self) -> int:
        return self.quantity.size

    def where(self, i: int, column: str | None = None) -> str:
        """``"DATA.csv row 3 (line 5), column 'eps'"``: where a message points."""
        text = f"{self.source} row {i + 1}"
        if self.lines is not None:
            text += f" (line {int(self.lines[i])})"
        return text + (f", column {column!r}" if column else "")

    @property
    def is_profile(self) -> np.ndarray:
        """Which rows measure a profile at ``xi``."""
        return np.isin(self.quantity, profile_quantities())

    def given(self, name: str) -> np.ndarray:
        """Which rows give input ``name`` (all False when there is no such column)."""
        col = self.columns.get(name)
        return np.zeros(len(self), dtype=bool) if col is None else ~np.isnan(col)


def read_data(data, *, source: str | None = None) -> Measurements:
    """The measurements of ``data``: a CSV path, a mapping of columns or an xarray Dataset.

    Parameters
    ----------
    data : str, os.PathLike, Mapping or xarray.Dataset
        A CSV file (a header line, then one measurement per line; lines starting with ``#`` are
        comments; numbers may be fractions ``1/30``; an empty cell gives nothing), a mapping of
        column name to a sequence (NaN or None where a row gives nothing), or a Dataset whose
        variables are the columns along one dimension. A :class:`Measurements` passes through.
    source : str, optional
        What messages call the table (default: the path, or ``"data"``).

    Returns
    -------
    Measurements

    Raises
    ------
    DataError
        (a :class:`~cosserat_channel.parameters.ParameterError`) naming the row and the column of
        the first bad cell: a missing or unknown column, an unknown quantity, NaN, a standard
        error that is not positive, ``xi`` outside [0, 1] or missing on a profile row, an input
        outside its range.
    """
    if isinstance(data, Measurements):
        return data
    lines = None
    if isinstance(data, (str, os.PathLike)):
        source = source or os.fspath(data)
        columns, lines = _read_csv(os.fspath(data), source)
    elif isinstance(data, Mapping):
        columns = {str(k): _column(v, str(k), source or "data") for k, v in data.items()}
    elif hasattr(data, "data_vars") and hasattr(data, "dims"):  # an xarray Dataset
        if len(data.dims) != 1:
            raise DataError(f"{source or 'data'}: a Dataset of measurements has one dimension "
                            f"(one measurement per element); got {tuple(data.dims)}")
        names = list(data.data_vars) + [c for c in data.coords if data[c].ndim == 1]
        columns = {str(k): _column(data[k].values, str(k), source or "data") for k in names}
    else:
        raise DataError("data must be a CSV path, a mapping of columns or an xarray Dataset; got "
                        f"{type(data).__name__}")
    return _checked(columns, source or "data", lines)


def _read_csv(path: str, source: str) -> tuple[dict, np.ndarray]:
    try:
        with open(path, encoding="utf-8", newline="") as f:
            numbered = [(n, line) for n, line in enumerate(f, start=1)
                        if line.strip() and not line.lstrip().startswith("#")]
    except UnicodeDecodeError:
        raise DataError(f"{source}: not a text (UTF-8) CSV file") from None
    except OSError as exc:
        raise DataError(f"{source}: cannot read: {exc.strerror or exc}") from None
    if not numbered:
        raise DataError(f"{source}: no header line (expected e.g. 'quantity,value,std_error,eps')")
    reader = csv.reader(line for _, line in numbered)
    try:
        rows = list(reader)
    except csv.Error as exc:  # a cell beyond the csv module's field limit, a NUL byte
        n = numbered[min(reader.line_num, len(numbered)) - 1][0]
        raise DataError(f"{source} line {n}: cannot be read as CSV ({exc})") from None
    header = [h.strip() for h in rows[0]]
    if len(header) == 1 and ";" in header[0]:
        raise DataError(f"{source}: the columns are separated by ';'; the file must be "
                        "comma-separated (e.g. 'quantity,value,std_error,eps')")
    lines = np.array([n for n, _ in numbered[1:]], dtype=np.int64)
    columns: dict = {h: [] for h in header}
    if len(columns) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(f"{source}: column {dup!r} appears twice in the header")
    for (n, _), cells in zip(numbered[1:], rows[1:]):
        if len(cells) != len(header):
            raise DataError(f"{source} line {n}: {len(cells)} cells where the header has "
                            f"{len(header)}")
        for h, cell in zip(header, cells):
            columns[h].append(cell.strip())
    _check_names(columns, source)
    out = {}
    for h, cells in columns.items():
        if h == QUANTITY:
            out[h] = np.array(cells, dtype=object)
            continue
        values = np.empty(len(cells))
        for i, cell in enumerate(cells):
            try:
                values[i] = parse_number(cell) if cell else math.nan
            except ValueError:
                raise DataError(f"{source} row {i + 1} (line {lines[i]}), column {h!r}: "
                                f"expected a number or a fraction a/b; got {cell!r}") from None
        out[h] = values
    return out, lines


def _column(values, name: str, source: str) -> np.ndarray:
    if name == QUANTITY:
        return np.array([str(v) for v in np.atleast_1d(np.asarray(values, dtype=object))],
                        dtype=object)
    arr = np.atleast_1d(np.asarray(values, dtype=object))
    out = np.empty(arr.shape[0] if arr.ndim else 1)
    if arr.ndim != 1:
        raise DataError(f"{source}, column {name!r}: expected one value per row; got shape "
                        f"{arr.shape}")
    for i, v in enumerate(arr):
        if v is None:
            out[i] = math.nan
            continue
        if isinstance(v, (bool, np.bool_, bytes)):
            raise DataError(f"{source} row {i + 1}, column {name!r}: expected a number; got {v!r}")
        try:
            out[i] = parse_number(v) if isinstance(v, str) else float(v)
        except (TypeError, ValueError, OverflowError):
            raise DataError(f"{source} row {i + 1}, column {name!r}: expected a number; "
                            f"got {v!r}") from None
    return out


def _check_names(columns, source: str) -> None:
    for name in columns:
        if name not in (*REQUIRED, XI) and name not in INPUTS:
            raise DataError(f"{source}: unknown column {name!r}; allowed: "
                            f"{', '.join((*REQUIRED, XI, *INPUTS))}")


def _checked(columns: dict, source: str, lines) -> Measurements:
    missing = [c for c in REQUIRED if c not in columns]
    if missing:
        raise DataError(f"{source}: missing column(s) {', '.join(missing)}; a table has "
                        f"{', '.join(REQUIRED)}, xi for profiles, and the inputs that vary by row")
    _check_names(columns, source)
    sizes = {name: len(col) for name, col in columns.items()}
    if len(set(sizes.values())) > 1:
        raise DataError(f"{source}: the columns have different lengths: "
                        + ", ".join(f"{k} {v}" for k, v in sizes.items()))
    n = sizes[QUANTITY]
    if n == 0:
        raise DataError(f"{source}: no measurements (the table has no rows)")
    quantity = np.asarray(columns[QUANTITY], dtype=object)
    xi = columns.get(XI, np.full(n, math.nan))
    data = Measurements(quantity.astype(str), columns[VALUE], columns[STD_ERROR], xi,
                        {k: v for k, v in columns.items() if k in INPUTS}, source, lines)
    scalar, profile = quantities(), profile_quantities()
    for i in range(n):
        q = str(data.quantity[i])
        if q not in scalar and q not in profile:
            raise DataError(f"{data.where(i, QUANTITY)}: unknown quantity {q!r}; a row measures "
                            f"one of {', '.join(scalar)}, or a profile ({', '.join(profile)}) at xi")
        if not math.isfinite(data.value[i]):
            raise DataError(f"{data.where(i, VALUE)}: the value must be a finite number; got "
                            f"{float(data.value[i])!r}")
        if not (math.isfinite(data.std_error[i]) and data.std_error[i] > 0):
            raise DataError(f"{data.where(i, STD_ERROR)}: the standard error must be a positive "
                            f"finite number; got {float(data.std_error[i])!r}")
        if q in profile:
            if not 0.0 <= data.xi[i] <= 1.0:  # False for NaN
                raise DataError(f"{data.where(i, XI)}: the profile {q} needs xi in [0, 1]; got "
                                f"{'nothing' if math.isnan(data.xi[i]) else repr(data.xi[i])}")
        elif not math.isnan(data.xi[i]):
            raise DataError(f"{data.where(i, XI)}: xi is for profile quantities "
                            f"({', '.join(profile)}); {q} is a scalar output")
    for name, col in data.columns.items():
        param = INPUTS[name]
        for i in np.flatnonzero(~np.isnan(col)):
            try:
                param.check(float(col[i]), data.where(i, name))
            except ParameterError as exc:
                raise DataError(str(exc)) from None
    return data
