"""Weighted least squares of the model against measurements: :func:`fit` and :class:`FitResult`.

The residual of a row is ``(prediction - value) / std_error``; :func:`scipy.optimize.least_squares`
(trust-region reflective, inside the bounds) minimises their sum of squares. The covariance of
the estimates is ``(J^T J)^-1`` of the residuals' Jacobian at the optimum: the standard errors
are taken as known (as measured), so ``chi2/dof`` near 1 says the model and the errors agree,
and it is reported, not folded into the covariance.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .. import status as st
from ..parameters import DEFAULT_ATOL, ParameterError, parse_number
from .data import INPUTS, DataError, Measurements, read_data
from .model import NO_VALUE, OUTSIDE, FitError, Problem, jacobian

__all__ = ["fit", "FitResult", "FitError", "FitWarning", "DEFAULT_RTOL", "COND_MAX"]

# The fit's solves are tighter than a point's default (1e-8): the central differences' error
# goes as rtol^(2/3), and 1e-10 costs a point some 30 % more.
DEFAULT_RTOL = 1e-10
# Above this condition number of the column-scaled Jacobian a parameter combination is not
# determined by the data: a relative change of 1/COND_MAX in the data moves it by O(1).
COND_MAX = 1e6
# Above this chi2/dof the model is nowhere near the data (residuals of 100 standard errors a row
# on average): rather a unit (%, kPa) than the model, said in a warning.
CHI2_DOF_FAR = 1e4
# A free input's start when none is given: the paper's reference point (docs/model.md, "Defaults
# throughout"), or the input's own default (the closure constants).
START = {"eps": 1.0 / 30.0, "L": 10.0, "K": 0.5, "A": 1.0 / 3.0, "N": 1.0}


class FitWarning(UserWarning):
    """Something to know about a finished fit (one line each): a bound reached, the edge of the
    solvable region met, a combination of parameters the data do not determine."""


@dataclass
class FitResult:
    """The outcome of :func:`fit`.

    Attributes
    ----------
    names : tuple of str
        The free parameters, in the order of the arrays below.
    estimates, std_errors : numpy.ndarray
        The least-squares estimates and their standard errors (NaN where not determined).
    covariance, correlation : numpy.ndarray
        ``(p, p)``.
    chi2 : float
        Sum of squared residuals; ``dof`` = rows - free parameters; :attr:`chi2_dof` their ratio.
    residuals : numpy.ndarray
        Per row, ``(prediction - value) / std_error``.
    predictions : numpy.ndarray
        Per row, the model's value at the estimates.
    status : list of str
        Per row, the status name at the estimates (``outside_domain`` for a point outside the
        parameters' ranges, ``no_value`` where the quantity is NaN at a solved point).
    data : Measurements
    fixed, bounds : dict
    start : numpy.ndarray
    condition_number : float
        Of the Jacobian with unit-norm columns (:data:`COND_MAX` is where a warning starts).
    jacobian : numpy.ndarray
        ``d residual / d parameter`` at the estimates, ``(n, p)``.
    jacobian_method : str
        ``"analytic"`` or ``"central differences"``.
    warnings : list of str
        What :func:`fit` warned of, one line each.
    success : bool
        Whether the optimiser met its convergence test; ``message`` says which.
    n_evaluations, n_solves : int
        Residual evaluations and point integrations (of :func:`cosserat_channel.solve` and
        :func:`~cosserat_channel.solver.point.solve_point`) spent.
    """

    names: tuple
    estimates: np.ndarray
    std_errors: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    chi2: float
    dof: int
    residuals: np.ndarray
    predictions: np.ndarray
    status: list
    data: Measurements
    fixed: dict
    bounds: dict
    start: np.ndarray
    condition_number: float
    jacobian: np.ndarray
    jacobian_method: str
    success: bool
    message: str
    n_evaluations: int
    n_solves: int
    warnings: list = field(default_factory=list)

    @property
    def chi2_dof(self) -> float:
        """``chi2 / dof`` (NaN with no degrees of freedom)."""
        return self.chi2 / self.dof if self.dof > 0 else math.nan

    @property
    def params(self) -> dict:
        """``{name: estimate}``."""
        return dict(zip(self.names, self.estimates.tolist()))

    @property
    def errors(self) -> dict:
        """``{name: standard error}``."""
        return dict(zip(self.names, self.std_errors.tolist()))

    def ellipse(self, x: str, y: str, level: float = 0.95, n: int = 241):
        """The boundary of the ``level`` confidence region of parameters ``x`` and ``y`` jointly,
        ``(x values, y values)`` of ``n`` points (closed: the last is the first).

        The region of the linearised fit, ``d^T C^-1 d <= q`` with ``C`` the pair's covariance
        and ``q = -2 ln(1 - level)`` (the ``level`` quantile of chi^2 with 2 degrees of freedom);
        NaN where the pair's covariance is not determined.
        """
        i, j = self._pair(x, y)
        if not 0.0 < level < 1.0:
            raise ValueError(f"level must be in (0, 1); got {level!r}")
        C = self.covariance[np.ix_([i, j], [i, j])]
        centre = self.estimates[[i, j]]
        if not np.all(np.isfinite(C)):
            return np.full(n, np.nan), np.full(n, np.nan)
        lam, vec = np.linalg.eigh(C)
        t = np.linspace(0.0, 2.0 * np.pi, n)
        radius = math.sqrt(-2.0 * math.log1p(-level))
        pts = centre[:, None] + radius * vec @ (np.sqrt(np.maximum(lam, 0.0))[:, None]
                                                * np.vstack([np.cos(t), np.sin(t)]))
        return pts[0], pts[1]

    def mahalanobis(self, x: str, y: str, xs, ys) -> np.ndarray:
        """The distance of each point ``(xs, ys)`` from the estimate in standard deviations of
        the pair ``(x, y)`` (the Mahalanobis distance ``sqrt(d^T C^-1 d)``; the ``level``
        region of :meth:`ellipse` is where it is below ``sqrt(-2 ln(1 - level))``)."""
        i, j = self._pair(x, y)
        C = self.covariance[np.ix_([i, j], [i, j])]
        d = np.stack(np.broadcast_arrays(np.asarray(xs, dtype=float) - self.estimates[i],
                                         np.asarray(ys, dtype=float) - self.estimates[j]), -1)
        if not np.all(np.isfinite(C)):
            return np.full(d.shape[:-1], np.nan)
        w = np.linalg.solve(C, d.reshape(-1, 2).T).T.reshape(d.shape)
        return np.sqrt(np.maximum(np.sum(d * w, axis=-1), 0.0))

    def _pair(self, x: str, y: str) -> tuple[int, int]:
        for name in (x, y):
            if name not in self.names:
                raise ValueError(f"{name!r} is not a free parameter of this fit (free: "
                                 f"{', '.join(self.names)})")
        if x == y:
            raise ValueError(f"give two different parameters; got {x!r} twice")
        return self.names.index(x), self.names.index(y)

    def plot(self, path=None):
        """The residual figure (:func:`cosserat_channel.plot.fit.residuals_figure`); written to
        ``path`` when given."""
        from ..plot.fit import residuals_figure

        return residuals_figure(self, path=path)

    def to_dict(self) -> dict:
        """A JSON-ready dict (NaN and inf as None)."""
        head, tail = self._json_parts()
        return {**head, "rows": list(self._json_rows()), **tail}

    def json_chunks(self, rows_per_chunk: int = 10_000):
        """``json.dumps(self.to_dict(), allow_nan=False)`` piece by piece: the rows are encoded
        ``rows_per_chunk`` at a time, so writing a fit of a million rows holds a few of them,
        not a dict of each."""
        head, tail = self._json_parts()
        # "rows" stands between head and tail in to_dict: the text is head's without its "}",
        # the rows, and tail's without its "{".
        yield json.dumps(head, allow_nan=False)[:-1] + ', "rows": ['
        chunk = []
        first = True
        for row in self._json_rows():
            chunk.append(json.dumps(row, allow_nan=False))
            if len(chunk) == rows_per_chunk:
                yield ("" if first else ", ") + ", ".join(chunk)
                first, chunk = False, []
        if chunk:
            yield ("" if first else ", ") + ", ".join(chunk)
        yield "], " + json.dumps(tail, allow_nan=False)[1:]

    def _json_parts(self) -> tuple[dict, dict]:
        """What :meth:`to_dict` holds before its rows and after them."""
        head = {
            "free": list(self.names),
            "estimates": {k: _clean(v) for k, v in self.params.items()},
            "std_errors": {k: _clean(v) for k, v in self.errors.items()},
            "covariance": [[_clean(v) for v in row] for row in self.covariance],
            "correlation": [[_clean(v) for v in row] for row in self.correlation],
            "chi2": _clean(self.chi2), "dof": self.dof, "chi2_dof": _clean(self.chi2_dof),
            "condition_number": _clean(self.condition_number),
            "fixed": {k: _clean(v) for k, v in self.fixed.items()},
            "bounds": {k: [_clean(lo), _clean(hi)] for k, (lo, hi) in self.bounds.items()},
            "start": dict(zip(self.names, (_clean(v) for v in self.start))),
        }
        tail = {
            "jacobian_method": self.jacobian_method,
            "success": bool(self.success), "message": self.message,
            "n_evaluations": self.n_evaluations, "n_solves": self.n_solves,
            "warnings": list(self.warnings),
        }
        return head, tail

    def _json_rows(self):
        """Each row of :meth:`to_dict`'s ``rows``, one at a time."""
        for q, v, e, x, p, r, s in zip(self.data.quantity, self.data.value, self.data.std_error,
                                       self.data.xi, self.predictions, self.residuals,
                                       self.status):
            yield {"quantity": str(q), "value": _clean(v), "std_error": _clean(e),
                   **({"xi": _clean(x)} if math.isfinite(x) else {}),
                   "prediction": _clean(p), "residual": _clean(r), "status": s}

    def summary(self) -> str:
        """The estimates, their errors and correlations, and the fit's statistics, as text."""
        lines = [f"{'parameter':<10} {'estimate':>14} {'std error':>12}  relative"]
        for name, x, e in zip(self.names, self.estimates, self.std_errors):
            rel = f"{abs(e / x):.2%}" if x != 0 and math.isfinite(e) else "-"
            lines.append(f"{name:<10} {x:>14.8g} {e:>12.4g}  {rel}")
        if len(self.names) > 1:
            lines.append("correlation  " + "  ".join(
                f"{a}-{b} {self.correlation[i, j]:+.3f}" for i, a in enumerate(self.names)
                for j, b in enumerate(self.names) if j > i))
        ratio = (f"chi2/dof = {self.chi2_dof:.4g}" if self.dof > 0 else
                 "no chi2/dof (as many free parameters as measurements)")
        lines.append(f"chi2 = {self.chi2:.6g}, dof = {self.dof}, {ratio}, "
                     f"condition number = {self.condition_number:.3g}")
        # scipy's messages quote its option names in reST backticks: plain text here.
        lines.append(f"{len(self.data)} measurements, {self.n_evaluations} evaluations, "
                     f"{self.n_solves} solves, Jacobian: {self.jacobian_method}; "
                     f"{self.message.replace('`', '')}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()


def _clean(x) -> float | None:
    """A float for JSON: None for NaN and inf."""
    x = float(x)
    return x if math.isfinite(x) else None


def fit(data, free, fixed: Mapping | None = None, bounds: Mapping | None = None,
        start: Mapping | None = None, *, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL,
        workers: int = 1, max_evaluations: int = 200) -> FitResult:
    """Fit the model's inputs ``free`` to measurements by weighted least squares.

    Parameters
    ----------
    data : str, os.PathLike, Mapping, xarray.Dataset or Measurements
        One measurement per row (:func:`cosserat_channel.calibrate.read_data`): ``quantity``,
        ``value``, ``std_error``, ``xi`` for a profile, and the inputs that vary by row.
    free : str or sequence of str
        The inputs to fit (``"L,K"`` or ``["L", "K"]``): any of ``eps, L, K, A, N``, the
        material's (``d_p``, ``rho_p``, ``phi``, ``Lambda``, ...) and ``W``, ``delta_w``.
    fixed : mapping, optional
        Values for the inputs no row gives (numbers, or strings such as ``"1/3"``); a row's own
        cell takes precedence.
    bounds : mapping, optional
        ``{name: (lo, hi)}`` for free inputs (default: the input's allowed range).
    start : mapping, optional
        Where the search starts (default: the paper's reference point, ``L = 10, K = 0.5,
        A = 1/3, N = 1``, or the input's default; inside the bounds).
    rtol, atol : float
        The solver's tolerances.
    workers : int
        Threads of each vectorised solve (1: one core).
    max_evaluations : int
        The optimiser's budget of residual evaluations.

    Returns
    -------
    FitResult

    Raises
    ------
    DataError, FitError
        (both :class:`~cosserat_channel.parameters.ParameterError`) for bad data (naming the
        row and column), bad ``free``/``fixed``/``bounds``/``start``, or a start point at which a
        row has no solution.

    Warns
    -----
    FitWarning
        One line each: an estimate at a bound; the fit meeting points without a solution (their
        statuses); parameters the data do not determine (the condition number and the
        combination); no convergence within the budget.
    """
    from scipy.optimize import least_squares

    data = read_data(data)
    names = _free_names(free)
    fixed = _fixed_values(fixed, names)
    lo, hi = _bounds(bounds, names)
    x0 = _start(start, names, lo, hi, bounds or {})
    problem = Problem(data, names, fixed, rtol=rtol, atol=atol, workers=workers)
    made = problem.points(x0)
    for g in np.argsort(problem.first_row, kind="stable"):  # the first bad row is named
        pt, why = made[g]
        if pt is None:
            i = int(problem.first_row[g])
            raise DataError(why if data.source in why else f"{data.where(i)}: {why}")
    f0, s0 = problem.evaluate(x0[None, :])
    bad = np.flatnonzero(s0[0] != st.OK)
    if bad.size:
        i = int(bad[0])
        raise FitError(f"{data.where(i)}: no solution at the start "
                       f"({_at(names, x0)}): {_status_text(int(s0[0, i]))}; give another start")
    sigma = data.std_error
    with np.errstate(over="ignore", invalid="ignore"):
        r_start = (f0[0] - data.value) / sigma
        # chi2 sums the squares: a residual whose square is beyond a double is as unusable.
        beyond = ~np.isfinite(r_start * r_start * len(r_start))
    if beyond.any():
        i = int(np.flatnonzero(beyond)[0])
        raise DataError(f"{data.where(i)}: ((prediction - value)/std_error)^2 is beyond the range "
                        f"of a double at the start (value {float(data.value[i])!r}, std_error "
                        f"{float(data.std_error[i])!r}, prediction {float(f0[0][i])!r}); check the "
                        "units of value and std_error")
    # A row without a solution counts this much: more than any residual near the start, so
    # the trust region shrinks back into the solvable region.
    penalty = 1e3 * max(1.0, float(np.max(np.abs(r_start))))
    # The optimiser asks for the Jacobian at the point it last evaluated, and ends at the last
    # point it took a Jacobian at: those two evaluations are kept (two rows' worth each), not
    # every trial's.
    memo: dict = {"last": None, "jac": None}
    met: dict = {}

    def evaluate(x, for_jacobian=False):
        key = x.tobytes()
        hit = next((e for e in (memo["last"], memo["jac"]) if e is not None and e[0] == key),
                   None)
        if hit is None:
            pred, status = problem.evaluate(x[None, :])
            hit = (key, pred[0], status[0])
            codes, counts = np.unique(status[0][status[0] != st.OK], return_counts=True)
            for code, count in zip(codes.tolist(), counts.tolist()):
                met[code] = met.get(code, 0) + count
        memo["last"] = hit
        if for_jacobian:
            memo["jac"] = hit
        return hit[1], hit[2]

    def residuals(x):
        pred, status = evaluate(x)
        with np.errstate(over="ignore", invalid="ignore"):
            r = (pred - data.value) / sigma
        # A residual beyond a double (a prediction that grows without bound as the search
        # goes) counts as a row without a solution: the trust region shrinks back.
        return np.where((status == st.OK) & np.isfinite(r), r, penalty)

    last_info: dict = {}

    def jac(x):
        pred, status = evaluate(x, for_jacobian=True)
        J, info = jacobian(problem, x, (pred, status))
        last_info.clear()
        last_info.update(info)
        with np.errstate(over="ignore", invalid="ignore"):
            J /= sigma[:, None]  # in place: J is the Jacobian's own new array
        # A row whose derivative is not finite (next to the small-eps-L end of the domain)
        # steers nothing: the optimiser needs finite entries.
        J[~np.isfinite(J)] = 0.0
        return J

    n_eval = [0]

    def counted(x):
        n_eval[0] += 1
        return residuals(x)

    try:
        opt = least_squares(counted, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                            ftol=1e-12, xtol=1e-12, gtol=1e-10, max_nfev=max_evaluations)
    except (ValueError, np.linalg.LinAlgError) as exc:  # scipy's own checks of what it met
        raise FitError(f"the optimiser cannot go on from {_at(names, x0)} "
                       f"({' '.join(str(exc).split())}); check the data's units, or give "
                       "another start or bounds") from None
    x = opt.x
    pred, status = evaluate(x)
    r = (pred - data.value) / sigma
    J, info = jacobian(problem, x, (pred, status))
    with np.errstate(over="ignore", invalid="ignore"):
        J /= sigma[:, None]
    # A row without a finite derivative at the estimate (no solution there, or next to the
    # small-eps-L end of the domain) gives the covariance nothing; said below.
    finite = np.isfinite(J)
    unsteered = int((~finite.all(axis=1) & (status == st.OK)).sum())
    J[~finite] = 0.0
    del finite
    try:
        cov, cond, null = _covariance(J)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise FitError(f"no covariance at {_at(names, x)} "
                       f"({' '.join(str(exc).split())}); check the data's units, or give "
                       "another start or bounds") from None
    se = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    chi2 = float(np.sum(np.where(status == st.OK, r, np.nan) ** 2))
    moving = _moving_elsewhere(problem, names, x, lo, hi, pred, np.linalg.norm(J, axis=0) == 0)
    notes = _warnings(names, x, moving, lo, hi, bounds or {}, opt, status, met, info, J, cond,
                      null, cov, data, chi2)
    if unsteered:
        notes.append(f"{unsteered} rows have no finite derivative at the estimate: the "
                     "standard errors leave them out")
    result = FitResult(
        names=names, estimates=x.copy(), std_errors=se, covariance=cov, correlation=corr,
        chi2=chi2, dof=len(data) - len(names), residuals=r, predictions=pred,
        status=_status_names(status), data=data, fixed=fixed,
        bounds={n: (float(a), float(b)) for n, a, b in zip(names, lo, hi)}, start=x0,
        condition_number=cond, jacobian=J, jacobian_method=info["method"],
        success=bool(opt.success), message=opt.message, n_evaluations=n_eval[0],
        n_solves=problem.n_solves, warnings=notes)
    for note in notes:
        warnings.warn(note, FitWarning, stacklevel=2)
    return result


# ---------------------------------------------------------------------------------------------
def _free_names(free) -> tuple:
    if isinstance(free, str):
        free = [s.strip() for s in free.split(",") if s.strip()]
    try:
        names = tuple(free)
    except TypeError:
        raise FitError("free must be a list of input names, e.g. ['L', 'K']") from None
    if not names:
        raise FitError("free: give at least one input to fit")
    for n in names:
        if n not in INPUTS:
            raise FitError(f"free: unknown input {n!r}; allowed: {', '.join(INPUTS)}")
    if len(set(names)) != len(names):
        raise FitError(f"free: {', '.join(names)} names an input twice")
    return names


def _mapping(value, what: str) -> dict:
    """``value`` (a mapping, or None) as a dict; FitError for anything else."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise FitError(f"{what} must be a mapping of input names to values, e.g. "
                       f"{{'A': '1/3'}}; got {type(value).__name__}")
    return dict(value)


def _fixed_values(fixed, names) -> dict:
    out = {}
    for k, v in _mapping(fixed, "fixed").items():
        if k not in INPUTS:
            raise FitError(f"fixed: unknown input {k!r}; allowed: {', '.join(INPUTS)}")
        if k in names:
            raise FitError(f"{k} is both free and fixed: give one")
        if isinstance(v, str):
            try:
                v = parse_number(v)
            except ValueError as exc:
                raise FitError(f"fixed {k}: {exc}") from None
        out[k] = _check(k, v, f"fixed {k}")
    return out


def _check(name: str, value, label: str) -> float:
    """``value`` inside input ``name``'s range, or a :class:`FitError` saying so."""
    try:
        return INPUTS[name].check(value, label)
    except ParameterError as exc:
        raise FitError(str(exc)) from None
    except (TypeError, ValueError, OverflowError):
        raise FitError(f"{label}: expected a number; got {value!r}") from None


def _bounds(bounds, names):
    lo = np.array([INPUTS[n].lo for n in names], dtype=np.float64)
    hi = np.array([INPUTS[n].hi for n in names], dtype=np.float64)
    for k, pair in _mapping(bounds, "bounds").items():
        if k not in names:
            raise FitError(f"bounds: {k!r} is not a free input (free: {', '.join(names)})")
        try:
            a, b = (parse_number(v) if isinstance(v, str) else float(v) for v in pair)
        except (TypeError, ValueError, OverflowError):
            raise FitError(f"bounds {k}: expected two numbers lo, hi; got {pair!r}") from None
        param = INPUTS[k]
        j = names.index(k)
        if not (a < b) or a < param.lo or b > param.hi or math.isnan(a) or math.isnan(b):
            raise FitError(f"bounds {k} = {a:g}:{b:g} must be lo < hi inside {k}'s range "
                           f"{param.interval}")
        lo[j], hi[j] = a, b
    return lo, hi


def _start(start, names, lo, hi, given_bounds) -> np.ndarray:
    start = _mapping(start, "start")
    for k in start:
        if k not in names:
            raise FitError(f"start: {k!r} is not a free input (free: {', '.join(names)})")
    x0 = np.empty(len(names))
    for j, n in enumerate(names):
        given = n in start
        v = start.get(n, START.get(n, INPUTS[n].default))
        if isinstance(v, str):
            try:
                v = parse_number(v)
            except ValueError as exc:
                raise FitError(f"start {n}: {exc}") from None
        if v is None:
            if n in given_bounds and math.isfinite(lo[j]) and math.isfinite(hi[j]):
                v = 0.5 * (lo[j] + hi[j])
            else:
                raise FitError(f"start: give a start value for {n} (it has no default), or its "
                               "bounds")
        v = _check(n, v, f"start {n}")
        if not lo[j] < v < hi[j]:
            if given:
                raise FitError(f"start {n} = {v:g} is outside its bounds {lo[j]:g}:{hi[j]:g}")
            # the default start is outside the given bounds: start inside them
            v = (0.5 * (lo[j] + hi[j]) if math.isfinite(hi[j] - lo[j])
                 else (lo[j] + abs(lo[j]) + 1.0 if v <= lo[j] else hi[j] - abs(hi[j]) - 1.0))
        x0[j] = v
    return x0


def _covariance(J):
    """``((J^T J)^-1, condition number, null direction)`` through the SVD of the column-scaled J.

    Columns are scaled to unit norm, so the condition number measures how well the data
    separate the parameters, not their units. Directions with singular values below
    ``1e-12 s_max`` are not determined: their parameters get NaN variances.
    """
    p = J.shape[1]
    norms = np.linalg.norm(J, axis=0)
    zero = norms == 0
    scaled = J / np.where(zero, 1.0, norms)
    _, s, vt = np.linalg.svd(scaled, full_matrices=False)
    s_full = np.zeros(p)
    s_full[:s.size] = s
    cond = s_full[0] / s_full[-1] if s_full[-1] > 0 else math.inf
    keep = s_full > 1e-12 * s_full[0]
    vt_full = np.zeros((p, p))
    vt_full[:vt.shape[0]] = vt
    inv = (vt_full[keep].T / s_full[keep] ** 2) @ vt_full[keep]
    cov = inv / np.outer(np.where(zero, 1.0, norms), np.where(zero, 1.0, norms))
    undetermined = zero.copy()
    for k in np.flatnonzero(~keep):
        undetermined |= np.abs(vt_full[k]) > 1e-3
    if p > vt.shape[0]:  # fewer rows than parameters: the rest of the space is null
        undetermined[:] = True
    cov[undetermined, :] = np.nan
    cov[:, undetermined] = np.nan
    null = vt_full[-1] / np.where(zero, 1.0, norms) if p else None
    return cov, cond, null


_OWN_STATUS = {OUTSIDE: ("outside_domain", "the point is outside the parameters' ranges"),
               NO_VALUE: ("no_value", "the point solves but the quantity has no value (NaN) there")}


def _status_name(code: int) -> str:
    return _OWN_STATUS[code][0] if code in _OWN_STATUS else st.Status(code).name


def _status_names(codes: np.ndarray) -> list:
    """The status name of each code, one string object per distinct code (a list of a million
    rows holds a million references, not a million strings)."""
    distinct, inverse = np.unique(codes, return_inverse=True)
    names = np.array([_status_name(int(c)) for c in distinct] or [""], dtype=object)
    return names[inverse.ravel()].tolist()


def _status_text(code: int) -> str:
    name, message = _OWN_STATUS.get(code) or (st.Status(code).name, st.Status(code).message)
    return f"{name} ({message})"


def _at(names, x) -> str:
    return ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, x))


def _moving_elsewhere(problem, names, x, lo, hi, pred, still) -> dict:
    """For each parameter ``j`` that changes no prediction at ``x`` (``still[j]``), a value of
    it within its bounds where the predictions differ from ``pred`` (its usual start, or x10,
    x1/10 of its estimate), if one does: the data are flat at the estimate only, not everywhere,
    and another start may find what they determine."""
    found = {}
    for j in np.flatnonzero(still):
        tries = [START.get(names[j], INPUTS[names[j]].default), 10.0 * x[j], 0.1 * x[j]]
        tries = [v for v in tries if v is not None and lo[j] < v < hi[j] and v != x[j]]
        if not tries:
            continue
        thetas = np.repeat(x[None, :], len(tries), axis=0)
        thetas[:, j] = tries
        other, status = problem.evaluate(thetas)
        ok = (status == st.OK) & np.isfinite(pred)
        for k, v in enumerate(tries):
            if (other[k][ok[k]] != pred[ok[k]]).any():
                found[j] = v
                break
    return found


def _warnings(names, x, moving, lo, hi, given_bounds, opt, status, met, info, J, cond, null,
              cov, data, chi2) -> list:
    notes = []
    for j, n in enumerate(names):
        for side, bound in (("lower", lo[j]), ("upper", hi[j])):
            close = math.isfinite(bound) and abs(x[j] - bound) <= 1e-6 * max(abs(bound), 1e-3)
            if close or opt.active_mask[j] == (-1 if side == "lower" else 1):
                where = "given" if n in given_bounds else "allowed"
                notes.append(f"{n} = {x[j]:.6g} is at its {side} bound {bound:g} (the {where} "
                             f"range): the data pull it further; its standard error is that of "
                             f"an interior optimum and understates the uncertainty")
    bad = np.flatnonzero(status != st.OK)
    if bad.size:
        codes = sorted(set(int(status[i]) for i in bad))
        notes.append(f"no solution at the estimates ({_at(names, x)}) for rows "
                     f"{', '.join(str(i + 1) for i in bad[:10])}: "
                     + "; ".join(_status_text(c) for c in codes))
    elif met:
        edge = (f"; the estimate lies at its edge ({', '.join(info['one_sided'])}: one-sided "
                "differences)") if info["one_sided"] else ""
        notes.append("the fit ran into the region without a solution: "
                     + "; ".join(f"{_status_text(c)} at {k} trial points"
                                 for c, k in sorted(met.items())) + edge)
    norms = np.linalg.norm(J, axis=0)
    for j in np.flatnonzero(norms == 0):
        if j in moving:
            notes.append(f"{names[j]} does not change any prediction at {names[j]} = "
                         f"{x[j]:.6g}, but does at {names[j]} = {moving[j]:.6g}: the fit is stuck "
                         "where the model is flat; give another start")
        else:
            notes.append(f"{names[j]} does not change any prediction: these data cannot "
                         "determine it")
    if len(names) > 1 and cond > COND_MAX and not (norms == 0).any():
        direction = null / np.where(x != 0, np.abs(x), 1.0)  # relative changes d theta/|theta|
        direction = direction / np.max(np.abs(direction))
        combo = " ".join(f"{c:+.3f} d{n}/{n}" for c, n in zip(direction, names) if abs(c) > 1e-3)
        notes.append(f"not identifiable from these data: the Jacobian's condition number is "
                     f"{cond:.3g} (> {COND_MAX:g}); the change {combo} leaves the predictions "
                     "unchanged to first order")
    se = np.sqrt(np.abs(np.diag(cov)))
    for j in np.flatnonzero((se > np.abs(x)) & (norms > 0)):
        notes.append(f"{names[j]} = {x[j]:.6g} +- {se[j]:.3g}: the data hardly determine it (its "
                     "standard error exceeds the estimate)")
    if len(data) < len(names):
        notes.append(f"{len(data)} measurements for {len(names)} free parameters: "
                     "underdetermined")
    if not opt.success or opt.status == 0:
        notes.append(f"the optimiser stopped without converging: {opt.message}")
    dof = len(data) - len(names)
    if dof > 0 and chi2 > CHI2_DOF_FAR * dof:
        notes.append(f"chi2/dof = {chi2 / dof:.3g}: the model is far from these data at the "
                     f"estimates (over {math.sqrt(CHI2_DOF_FAR):g} standard errors a row); check "
                     "the units of value and std_error (e.g. % where the quantity is a fraction)")
    return notes
