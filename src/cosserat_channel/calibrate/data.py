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


# Bounds of a CSV table, checked as it is read (a device such as /dev/zero never ends a line, a
# FIFO may never end): lines (comments and blank ones included), and characters of one line (a
# measurement is a short line; the csv module's own cell limit is 131,072).
MAX_LINES = 10_000_000
MAX_LINE_CHARS = 1 << 20


def _numbered_lines(f, source: str, where: list):
    """The header and data lines of ``f``, one at a time (comments and blank lines skipped);
    ``where[0]`` is the number of the line last given. DataError past :data:`MAX_LINES` lines
    or :data:`MAX_LINE_CHARS` characters in one line."""
    n = 0
    while True:
        line = f.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        n += 1
        if len(line) > MAX_LINE_CHARS:
            raise DataError(f"{source} line {n}: longer than {MAX_LINE_CHARS:,} characters (at "
                            "most that per line: a measurement is one short line)")
        if n > MAX_LINES:
            raise DataError(f"{source}: more than {MAX_LINES:,} lines (at most that many in a "
                            "table; fit a sample, or merge repeated measurements)")
        if line.strip() and not line.lstrip().startswith("#"):
            where[0] = n
            yield line


def _read_csv(path: str, source: str) -> tuple[dict, np.ndarray]:
    """Read a CSV table as it streams: memory grows with the numbers read (8 bytes a cell), not
    with the text, and nothing beyond :data:`MAX_LINES` or :data:`MAX_LINE_CHARS` is kept."""
    from array import array

    where = [0]
    try:
        with open(path, encoding="utf-8", newline="") as f:
            reader = csv.reader(_numbered_lines(f, source, where))
            try:
                header = next(reader, None)
                if header is None:
                    raise DataError(f"{source}: no header line (expected e.g. "
                                    "'quantity,value,std_error,eps')")
                header = [h.strip() for h in header]
                if len(header) == 1 and ";" in header[0]:
                    raise DataError(f"{source}: the columns are separated by ';'; the file must "
                                    "be comma-separated (e.g. 'quantity,value,std_error,eps')")
                if len(set(header)) != len(header):
                    dup = next(h for h in header if header.count(h) > 1)
                    raise DataError(f"{source}: column {dup!r} appears twice in the header")
                _check_names(dict.fromkeys(header), source)
                lines = array("q")
                names: dict = {}  # one string object per distinct quantity
                quantity: list = []
                values = {h: array("d") for h in header if h != QUANTITY}
                for cells in reader:
                    n = where[0]
                    if len(cells) != len(header):
                        raise DataError(f"{source} line {n}: {len(cells)} cells where the "
                                        f"header has {len(header)}")
                    lines.append(n)
                    for h, cell in zip(header, cells):
                        cell = cell.strip()
                        if h == QUANTITY:
                            quantity.append(names.setdefault(cell, cell))
                            continue
                        try:
                            v = parse_number(cell) if cell else math.nan
                        except ValueError:
                            raise DataError(f"{source} row {len(lines)} (line {n}), column "
                                            f"{h!r}: expected a number or a fraction a/b; got "
                                            f"{cell!r}") from None
                        values[h].append(v)
            except csv.Error as exc:  # a cell beyond the csv module's field limit, a NUL byte
                raise DataError(f"{source} line {where[0]}: cannot be read as CSV ({exc})") \
                    from None
    except UnicodeDecodeError:
        raise DataError(f"{source}: not a text (UTF-8) CSV file") from None
    except OSError as exc:
        raise DataError(f"{source}: cannot read: {exc.strerror or exc}") from None
    out = {h: np.frombuffer(v, dtype=np.float64).copy() if len(v) else np.empty(0)
           for h, v in values.items()}
    if QUANTITY in header:
        out[QUANTITY] = np.array(quantity, dtype=object)
    out = {h: out[h] for h in header}
    return out, np.frombuffer(lines, dtype=np.int64).copy() if len(lines) else \
        np.empty(0, dtype=np.int64)


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
    # Checked column by column (time linear in the rows), then the first bad row row by row, so
    # that the message names the first bad cell as reading row by row would.
    kinds = np.isin(data.quantity, scalar) | np.isin(data.quantity, profile)
    profiled = np.isin(data.quantity, profile)
    with np.errstate(invalid="ignore"):
        bad = (~kinds | ~np.isfinite(data.value) | ~(np.isfinite(data.std_error)
                                                      & (data.std_error > 0))
               | np.where(profiled, ~((data.xi >= 0.0) & (data.xi <= 1.0)), ~np.isnan(data.xi)))
    for i in np.flatnonzero(bad)[:1]:
        _check_row(data, int(i), scalar, profile)
    for name, col in data.columns.items():
        param = INPUTS[name]
        given = ~np.isnan(col)
        if not given.any():
            continue
        # Each distinct value once (a parameter's check is a scalar's), the first row holding it
        # named: the first bad row in order is the first of the bad values' first rows.
        uniq, first = np.unique(col[given], return_index=True)
        rows = np.flatnonzero(given)[first]
        for k in np.argsort(rows, kind="stable"):
            try:
                param.check(float(uniq[k]), data.where(int(rows[k]), name))
            except ParameterError as exc:
                raise DataError(str(exc)) from None
    return data


def _check_row(data: Measurements, i: int, scalar, profile) -> None:
    """DataError naming the first bad cell of row ``i`` (its quantity, value, standard error,
    xi), if there is one."""
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
                            f"{'nothing' if math.isnan(data.xi[i]) else repr(float(data.xi[i]))}")
    elif not math.isnan(data.xi[i]):
        raise DataError(f"{data.where(i, XI)}: xi is for profile quantities "
                        f"({', '.join(profile)}); {q} is a scalar output")
