"""The model as a fit sees it: the free parameters give each row its point, the point its
prediction, and :func:`jacobian` the predictions' derivatives.

A row's inputs come from its own cells first, then from the fit's free or fixed values, then
from the material's defaults. ``eps`` comes from the row's ``eps``, or from ``d_p/W``
(:func:`~cosserat_channel.parameters.eps_from_width`); ``N`` from ``N``, or from
``sin(phi)/tan(delta_w)`` (:func:`~cosserat_channel.parameters.N_from_friction`). Rows with
distinct points are solved together: the scalar rows of every trial in one
:func:`cosserat_channel.solve` call (per material), the profile rows one
:func:`~cosserat_channel.solver.point.solve_point` per distinct point, with all its ``xi``.
"""

from __future__ import annotations

import math

import numpy as np

from .. import outputs as out_
from ..parameters import (DEFAULT_ATOL, DIMS, MATERIAL, MATERIAL_REQUIRED, ParameterError,
                          N_from_friction, check_material, check_point, eps_from_width)
from .data import INPUTS, DataError, Measurements

__all__ = ["Problem", "FitError", "jacobian", "OUTSIDE", "NO_VALUE"]


class FitError(ParameterError):
    """A fit that cannot start: its free, fixed, bounds or start values, or a start without a
    solution. The message names the parameter or the row."""

# Two statuses of a row next to cosserat_channel.status.Status's (codes >= 0): its point, at
# some trial, is outside the parameters' ranges; or the point solves but the measured quantity
# has no value there (NaN, e.g. a closure without a root).
OUTSIDE = -1
NO_VALUE = -2

# Where eps and N come from when a row does not give them: (parameter, engineers' input, the
# material input it needs, the relation).
_DERIVED = (("eps", "W", "d_p", eps_from_width), ("N", "delta_w", "phi", N_from_friction))


class Problem:
    """The measurements, which inputs are free and which fixed, and the solver's settings.

    Parameters
    ----------
    data : Measurements
    free : tuple of str
        The fitted inputs (names of :data:`.data.INPUTS`), in the order of the vector ``theta``.
    fixed : dict
        Values of inputs shared by every row that does not give its own.
    rtol, atol : float
        The solver's tolerances.
    workers : int
        Threads of each :func:`cosserat_channel.solve` call.
    """

    def __init__(self, data: Measurements, free: tuple, fixed: dict, *, rtol: float,
                 atol: float = DEFAULT_ATOL, workers: int = 1):
        self.data, self.free, self.fixed = data, tuple(free), dict(fixed)
        self.rtol, self.atol, self.workers = rtol, atol, workers
        n = len(data)
        self.profile_rows = data.is_profile
        self.needs_material = np.array([not p and out_.OUTPUTS[q].material
                                        for q, p in zip(data.quantity, self.profile_rows)])
        self.n_solves = 0
        self.analytic = None  # whether solve_point's sensitivities cover every row (see jacobian)
        for direct, physical, _, _ in _DERIVED:
            both = data.given(direct) & data.given(physical)
            if both.any():
                i = int(np.flatnonzero(both)[0])
                raise DataError(f"{data.where(i)}: gives both {direct} and {physical} "
                                     f"(which gives {direct}): give one")
            glob = [k for k in (direct, physical) if k in self.free or k in self.fixed]
            if len(glob) == 2:
                raise FitError(f"{direct} and {physical} (which gives {direct}) are both "
                                     "fixed or free: give one")
        self._columns = {k: v for k, v in data.columns.items()}
        self._given = {k: data.given(k) for k in INPUTS}  # once, not per row: time linear in n
        self._n = n

    # -----------------------------------------------------------------------------------------
    def inputs(self, theta) -> dict:
        """Every input of every row at ``theta``: ``{name: (n,) float64}``, NaN where none."""
        glob = dict(self.fixed)
        glob.update(zip(self.free, (float(t) for t in theta)))
        values = {}
        for name, param in INPUTS.items():
            col = self._columns.get(name)
            fill = glob.get(name, math.nan if param.default is None else param.default)
            values[name] = np.full(self._n, fill) if col is None else np.where(np.isnan(col),
                                                                               fill, col)
        return values

    def points(self, theta) -> list:
        """Each row's ``(point, material)`` at ``theta`` (``point`` the 5-tuple, ``material``
        None where the row needs none), or ``(None, message)`` where it is outside the model's
        domain or lacks an input."""
        v = self.inputs(theta)
        # Rows with the same inputs (values, which of them the row gives, whether it needs a
        # material) have the same point: each distinct row is made once (repeated measurements,
        # a profile's rows), so the time is numpy's over the rows plus Python's per distinct
        # row. A message names the first row of its kind (the first bad row is one).
        # Only the table's own columns vary by row; the rest hold one value for every row.
        keys = np.column_stack([v[k] for k in self._columns] + [self._given[k] for k in
                                                                self._columns]
                               + [self.needs_material]).astype(np.float64)
        rows = np.ascontiguousarray(keys).view(np.dtype((np.void, 8 * keys.shape[1]))).ravel()
        _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        made = []
        for i in first:
            try:
                made.append(self._point(v, int(i)))
            except ParameterError as exc:
                made.append((None, str(exc)))
        return [made[k] for k in inverse.ravel()]

    def _point(self, v: dict, i: int):
        data = self.data
        given = {}
        for direct, physical, needs, relation in _DERIVED:
            if self._given[direct][i] or (not self._given[physical][i]
                                         and not math.isnan(v[direct][i])):
                given[direct] = v[direct][i]
            elif not math.isnan(v[physical][i]):
                if math.isnan(v[needs][i]):
                    raise ParameterError(f"{data.where(i)}: {physical} gives {direct} only with "
                                         f"{needs}: give {needs}")
                given[direct] = float(relation(float(v[needs][i]), float(v[physical][i])))
        missing = [d for d in DIMS if math.isnan(given.get(d, v[d][i]))]
        if missing:
            how = {"eps": "eps (or W with d_p)", "N": "N (or delta_w with phi)"}
            raise ParameterError(f"{data.where(i)}: no value for "
                                 f"{', '.join(how.get(d, d) for d in missing)}: give a column, a "
                                 "fixed value or a free parameter")
        point = check_point(*(given.get(d, v[d][i]) for d in DIMS))
        material = None
        if self.needs_material[i]:
            lacking = [k for k in MATERIAL_REQUIRED if math.isnan(v[k][i])]
            if lacking:
                raise ParameterError(f"{data.where(i)}: {data.quantity[i]} needs a material; no "
                                     f"value for {', '.join(lacking)}")
            material = check_material({k: float(v[k][i]) for k in MATERIAL})
        return point, material

    # -----------------------------------------------------------------------------------------
    def evaluate(self, thetas) -> tuple[np.ndarray, np.ndarray, dict]:
        """Predictions at each of ``thetas`` (shape ``(m, p)``).

        Returns
        -------
        predictions : numpy.ndarray, shape (m, n)
            NaN where a row has no solution.
        status : numpy.ndarray of int, shape (m, n)
            Each row's status code, :data:`OUTSIDE` where its point is outside the domain,
            :data:`NO_VALUE` where it solves but the quantity is NaN.
        outside : dict
            ``{(k, i): message}`` for the rows outside the domain.
        """
        thetas = np.atleast_2d(np.asarray(thetas, dtype=np.float64))
        m, n = thetas.shape[0], self._n
        pred = np.full((m, n), math.nan)
        status = np.full((m, n), OUTSIDE, dtype=np.int64)
        outside = {}
        scalar_jobs: dict = {}
        profile_jobs: dict = {}
        for k, theta in enumerate(thetas):
            for i, (point, material) in enumerate(self.points(theta)):
                if point is None:
                    outside[(k, i)] = material
                elif self.profile_rows[i]:
                    profile_jobs.setdefault(point, []).append(k * n + i)  # an int, not a tuple
                else:
                    key = None if material is None else tuple(material.items())
                    scalar_jobs.setdefault(key, []).append((k, i, point))
        quantity, xi = self.data.quantity, self.data.xi
        if scalar_jobs:
            from ..sweep.arrays import solve

            for key, jobs in scalar_jobs.items():
                # Each distinct point solved once (repeated measurements share it).
                where: dict = {}
                at = [where.setdefault(p, len(where)) for _, _, p in jobs]
                pts = np.array(list(where))
                names = sorted({quantity[i] for _, i, _ in jobs})
                ds = solve(*pts.T, material=None if key is None else dict(key), outputs=names,
                           rtol=self.rtol, atol=self.atol, workers=self.workers)
                self.n_solves += int(ds.attrs["n_solves"])
                codes = ds["status"].values
                cols = {q: ds[q].values for q in names}
                for j, (k, i, _) in zip(at, jobs):
                    status[k, i] = codes[j]
                    pred[k, i] = cols[quantity[i]][j]
        if profile_jobs:
            from ..solver.point import solve_point

            for point, jobs in profile_jobs.items():
                ks, rows = np.divmod(np.array(jobs, dtype=np.int64), n)
                r = solve_point(*point, rtol=self.rtol, atol=self.atol, profile=xi[rows],
                                outputs=[])
                self.n_solves += 1
                status[ks, rows] = int(r.status)
                if r.profile is not None:
                    for q in np.unique(quantity[rows]):
                        at = np.flatnonzero(quantity[rows] == q)
                        pred[ks[at], rows[at]] = np.asarray(r.profile[q])[at]
        status[(status == 0) & ~np.isfinite(pred)] = NO_VALUE
        return pred, status, outside


# ---------------------------------------------------------------------------------------------
# The Jacobian: the one place that decides how derivatives are computed
# ---------------------------------------------------------------------------------------------
def fd_step(theta: np.ndarray, rtol: float) -> np.ndarray:
    """Central-difference steps: truncation (h^2) balances the solve's noise (~rtol/h) at
    ``h ~ rtol^(1/3)`` relative, with a floor for parameters near 0 (K, A)."""
    rel = max(rtol, 1e-15) ** (1.0 / 3.0)
    return rel * np.maximum(np.abs(theta), 1e-2)


def jacobian(problem: Problem, theta, base: tuple | None = None) -> tuple[np.ndarray, dict]:
    """d prediction / d theta at ``theta``: shape ``(n, p)``, and what it met.

    Analytic from ``solve_point(..., sensitivities=True)`` where they cover every row and are
    all finite, else central differences (one-sided where a neighbour has no solution).

    Parameters
    ----------
    problem : Problem
    theta : array_like, shape (p,)
    base : tuple, optional
        ``problem.evaluate(theta)``'s ``(predictions[0], status[0])`` if already known.

    Returns
    -------
    J : numpy.ndarray, shape (n, p)
    info : dict
        ``method`` ("analytic" or "central differences"), ``one_sided`` (the parameters whose
        difference was one-sided somewhere: an edge of the solvable region is within a step),
        ``statuses`` (the status codes met by the neighbours that had no solution).
    """
    theta = np.asarray(theta, dtype=np.float64)
    if problem.analytic is not False:
        J, covered = _analytic(problem, theta)
        # Whether the sensitivities cover the rows depends on their quantities, not on theta:
        # found once per problem.
        if covered is not None:
            problem.analytic = covered
        if J is not None:
            return J, {"method": "analytic", "one_sided": [], "statuses": {}}
    return _central(problem, theta, base)


def _central(problem: Problem, theta, base):
    p = theta.size
    h = fd_step(theta, problem.rtol)
    shifted = np.repeat(theta[None, :], 2 * p, axis=0)
    shifted[np.arange(p) * 2, np.arange(p)] += h
    shifted[np.arange(p) * 2 + 1, np.arange(p)] -= h
    todo = shifted if base is not None else np.vstack([shifted, theta])
    pred, status, _ = problem.evaluate(todo)
    f0, s0 = base if base is not None else (pred[-1], status[-1])
    n = f0.size
    J = np.zeros((n, p))
    one_sided, statuses = [], {}
    for j in range(p):
        fp, fm = pred[2 * j], pred[2 * j + 1]
        okp, okm = status[2 * j] == 0, status[2 * j + 1] == 0
        ok0 = s0 == 0
        both = okp & okm
        J[both, j] = (fp[both] - fm[both]) / (2 * h[j])
        fwd = okp & ~okm & ok0
        J[fwd, j] = (fp[fwd] - f0[fwd]) / h[j]
        bwd = ~okp & okm & ok0
        J[bwd, j] = (f0[bwd] - fm[bwd]) / h[j]
        if (ok0 & ~both).any():
            one_sided.append(problem.free[j])
            for code in np.concatenate([status[2 * j][~okp], status[2 * j + 1][~okm]]):
                statuses[int(code)] = statuses.get(int(code), 0) + 1
    return J, {"method": "central differences", "one_sided": one_sided, "statuses": statuses}


def _analytic(problem: Problem, theta):
    """The Jacobian from ``solve_point(..., sensitivities=True)``: each row's derivatives with
    respect to its point and material, chained with the closed-form map from ``theta`` to them.

    Returns ``(J, covered)``: ``(None, False)`` where the solver's sensitivities do not cover
    what a row needs, ``(None, None)`` where a row's point (or a neighbour of the closed-form
    map) is outside the domain at this ``theta`` or a derivative is NaN (no solution, or
    unresolved: ``sensitivity_flags``); central differences then."""
    from ..solver import point as point_

    data = problem.data
    rows = problem.points(theta)
    if any(pt is None for pt, _ in rows):
        return None, None
    # d (row inputs) / d theta by differencing the closed-form map (no solve: exact to ~1e-10).
    p = theta.size
    dinputs = []
    for j in range(p):
        h = 1e-6 * max(abs(theta[j]), 1e-2)
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        rp, rm = problem.points(tp), problem.points(tm)
        if any(pt is None for pt, _ in rp + rm):
            return None, None
        # Rows of the same inputs share their point objects (Problem.points): one derivative
        # each, shared, not one dict per row.
        made: dict = {}
        dinputs.append([made.get((id(a), id(b))) or made.setdefault(
            (id(a), id(b)), _row_derivative(a, b, 2 * h)) for a, b in zip(rp, rm)])
    J = np.zeros((len(data), p))
    shared: dict = {}  # one key object per distinct (point, material, kind), as above
    keys = [shared.get((id(row), bool(problem.profile_rows[i]))) or shared.setdefault(
        (id(row), bool(problem.profile_rows[i])),
        (row[0], None if row[1] is None else tuple(row[1].items()),
         bool(problem.profile_rows[i])))
        for i, row in enumerate(rows)]
    groups: dict = {}  # the rows of each key, in order: one pass over the rows, not one per row
    for i, key in enumerate(keys):
        groups.setdefault(key, []).append(i)
    cache: dict = {}
    # profile rows first: where the solver has no profile sensitivities this gives up at once
    for i in sorted(range(len(rows)), key=lambda i: not problem.profile_rows[i]):
        pt, mat = rows[i]
        q = data.quantity[i]
        key = keys[i]
        if key not in cache:
            xi = data.xi[groups[key]] if problem.profile_rows[i] else None
            r = point_.solve_point(*pt, material=mat, rtol=problem.rtol, atol=problem.atol,
                                   profile=xi, sensitivities=True)
            problem.n_solves += 1
            # where each xi first stands in the profile solved
            first = {} if xi is None else {x: k for k, x in reversed(list(enumerate(xi)))}
            cache[key] = (r, first)
        r, first = cache[key]
        if problem.profile_rows[i]:
            k = first[data.xi[i]]
            sens = {name: np.asarray(v)[k] for name, v in
                    r.profile_sensitivities.get(q, {}).items()}
        else:
            sens = r.sensitivities.get(q, {})
        for j in range(p):
            total = 0.0
            for name, d in dinputs[j][i].items():
                if d == 0.0:
                    continue
                if name not in sens:
                    return None, False
                total += float(sens[name]) * d
            if not math.isfinite(total):  # a derivative the solver left unresolved
                return None, None
            J[i, j] = total
    return J, True


def _row_derivative(plus, minus, width) -> dict:
    """``{input: d input / d theta_j}`` of one row from its points at ``theta +- h``."""
    (pp, mp), (pm, mm) = plus, minus
    out = {d: (a - b) / width for d, a, b in zip(DIMS, pp, pm)}
    if mp is not None:
        out.update({k: (mp[k] - mm[k]) / width for k in mp})
    return out
