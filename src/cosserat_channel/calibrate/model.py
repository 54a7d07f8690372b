"""The model as a fit sees it: the free parameters give each row its point, the point its
prediction, and :func:`jacobian` the predictions' derivatives.

A row's inputs come from its own cells first, then from the fit's free or fixed values, then
from the material's defaults. ``eps`` comes from the row's ``eps``, or from ``d_p/W``
(:func:`~cosserat_channel.parameters.eps_from_width`); ``N`` from ``N``, or from
``sin(phi)/tan(delta_w)`` (:func:`~cosserat_channel.parameters.N_from_friction`). Rows with
distinct points are solved together: the scalar rows of every trial in one
:func:`cosserat_channel.solve` call (per material), the profile rows one
:func:`~cosserat_channel.solver.point.solve_point` per distinct point, at the distinct ``xi``
of its rows. What is per row is numpy over index arrays (rows to distinct rows to points).
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

    Rows with the same inputs (the values of the table's own input columns, which of them the
    row gives, whether it needs a material) have the same point at every ``theta``: they are
    one *distinct row*, found once here. Everything per row is then numpy over index arrays
    (:attr:`row_group` maps each row to its distinct row), and Python's work is per distinct
    row and per solve, so memory is that of a few arrays of the rows and time is linear in them.

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

    Attributes
    ----------
    row_group : numpy.ndarray of int, shape (n,)
        Each row's distinct row (an index into what :meth:`points` returns).
    first_row : numpy.ndarray of int
        Each distinct row's first row in the table (messages name it).
    """

    def __init__(self, data: Measurements, free: tuple, fixed: dict, *, rtol: float,
                 atol: float = DEFAULT_ATOL, workers: int = 1):
        self.data, self.free, self.fixed = data, tuple(free), dict(fixed)
        self.rtol, self.atol, self.workers = rtol, atol, workers
        n = len(data)
        self.profile_rows = data.is_profile
        scalar_names = np.unique(data.quantity[~self.profile_rows])
        self.needs_material = ~self.profile_rows & np.isin(
            data.quantity, [q for q in scalar_names if out_.OUTPUTS[q].material])
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
        self._n = n
        # The distinct rows: the table's own input columns (NaN where a row gives none) and
        # whether the row needs a material, compared as bytes.
        columns = dict(data.columns)
        keys = np.column_stack([np.where(np.isnan(c), np.nan, c) for c in columns.values()]
                               + [self.needs_material.astype(np.float64)])
        rows = np.ascontiguousarray(keys).view(np.dtype((np.void, 8 * keys.shape[1]))).ravel()
        _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        del keys, rows
        self.row_group = inverse.ravel().astype(np.intp)
        self.first_row = first.astype(np.intp)
        g = self.first_row
        self._columns = {k: c[g] for k, c in columns.items()}  # at each distinct row
        self._given = {k: data.given(k)[g] for k in INPUTS}
        self._needs_material = self.needs_material[g]
        # What each row measures, as an index into _names.
        self._names, code = np.unique(data.quantity, return_inverse=True)
        # Row indices in 4 bytes where they fit (a CSV has at most data.MAX_LINES rows).
        index = np.int32 if n < 2**31 else np.intp
        code = code.ravel().astype(index)
        self._profile = _Rows(self.row_group, np.flatnonzero(self.profile_rows), g.size, code)
        self._scalar = _Rows(self.row_group, np.flatnonzero(~self.profile_rows), g.size, code)
        del code
        # The distinct xi of each distinct row's profile rows, and each profile row's among them.
        p = self._profile
        xi = data.xi[p.rows]
        order = np.lexsort((xi, p.group_of))
        new = np.ones(order.size, dtype=bool)
        new[1:] = (p.group_of[order][1:] != p.group_of[order][:-1]) | (xi[order][1:]
                                                                        != xi[order][:-1])
        self._xi_of = np.empty(order.size, dtype=index)  # per profile row, in p.rows' order
        self._xi_of[order] = np.cumsum(new) - 1
        self._xi = xi[order][new]  # the distinct (distinct row, xi) pairs' xi
        self._xi_start = np.searchsorted(p.group_of[order][new], np.arange(g.size + 1))
        self._xi_of -= self._xi_start[p.group_of]  # the index within its distinct row's xi
        del xi, order, new
        # The scalar quantities of each distinct row (a solve computes only those asked for).
        s = self._scalar
        pairs = np.unique(s.group_of * self._names.size + s.code)
        del p.group_of, s.group_of  # (only for the above)
        self._scalar_names = [[] for _ in range(g.size)]
        for gq in pairs.tolist():
            self._scalar_names[gq // self._names.size].append(
                str(self._names[gq % self._names.size]))

    # -----------------------------------------------------------------------------------------
    def inputs(self, theta) -> dict:
        """Every input of every distinct row at ``theta``: ``{name: (g,) float64}``, NaN where
        none."""
        glob = dict(self.fixed)
        glob.update(zip(self.free, (float(t) for t in theta)))
        values = {}
        size = self.first_row.size
        for name, param in INPUTS.items():
            col = self._columns.get(name)
            fill = glob.get(name, math.nan if param.default is None else param.default)
            values[name] = np.full(size, fill) if col is None else np.where(np.isnan(col),
                                                                            fill, col)
        return values

    def points(self, theta) -> list:
        """Each distinct row's ``(point, material)`` at ``theta`` (``point`` the 5-tuple,
        ``material`` None where the row needs none), or ``(None, message)`` where it is outside
        the model's domain or lacks an input; :attr:`row_group` maps the rows to them. A message
        names the distinct row's first row."""
        v = self.inputs(theta)
        made = []
        for g in range(self.first_row.size):
            try:
                made.append(self._point(v, g))
            except ParameterError as exc:
                made.append((None, str(exc)))
        return made

    def _point(self, v: dict, g: int):
        data, i = self.data, int(self.first_row[g])
        given = {}
        for direct, physical, needs, relation in _DERIVED:
            if self._given[direct][g] or (not self._given[physical][g]
                                         and not math.isnan(v[direct][g])):
                given[direct] = v[direct][g]
            elif not math.isnan(v[physical][g]):
                if math.isnan(v[needs][g]):
                    raise ParameterError(f"{data.where(i)}: {physical} gives {direct} only with "
                                         f"{needs}: give {needs}")
                given[direct] = float(relation(float(v[needs][g]), float(v[physical][g])))
        missing = [d for d in DIMS if math.isnan(given.get(d, v[d][g]))]
        if missing:
            how = {"eps": "eps (or W with d_p)", "N": "N (or delta_w with phi)"}
            raise ParameterError(f"{data.where(i)}: no value for "
                                 f"{', '.join(how.get(d, d) for d in missing)}: give a column, a "
                                 "fixed value or a free parameter")
        point = check_point(*(given.get(d, v[d][g]) for d in DIMS))
        material = None
        if self._needs_material[g]:
            lacking = [k for k in MATERIAL_REQUIRED if math.isnan(v[k][g])]
            if lacking:
                raise ParameterError(f"{data.where(i)}: {data.quantity[i]} needs a material; no "
                                     f"value for {', '.join(lacking)}")
            material = check_material({k: float(v[k][g]) for k in MATERIAL})
        return point, material

    def _profile_xi(self, groups) -> tuple[np.ndarray, list]:
        """The distinct ``xi`` (ascending) that the profile rows of distinct rows ``groups``
        measure at, and for each group its rows' indices among them."""
        span = [slice(self._xi_start[g], self._xi_start[g + 1]) for g in groups]
        local = [self._xi_of[self._profile.start[g]:self._profile.start[g + 1]] for g in groups]
        if len(groups) == 1:
            return self._xi[span[0]], local
        xi, inv = np.unique(np.concatenate([self._xi[s] for s in span]), return_inverse=True)
        offset = np.cumsum([0] + [s.stop - s.start for s in span])
        return xi, [inv.ravel()[o + k] for o, k in zip(offset, local)]

    # -----------------------------------------------------------------------------------------
    def evaluate(self, thetas) -> tuple[np.ndarray, np.ndarray]:
        """Predictions at each of ``thetas`` (shape ``(m, p)``).

        Returns
        -------
        predictions : numpy.ndarray, shape (m, n)
            NaN where a row has no solution.
        status : numpy.ndarray of int, shape (m, n)
            Each row's status code, :data:`OUTSIDE` where its point is outside the domain,
            :data:`NO_VALUE` where it solves but the quantity is NaN.
        """
        thetas = np.atleast_2d(np.asarray(thetas, dtype=np.float64))
        m, n = thetas.shape[0], self._n
        pred = np.full((m, n), math.nan)
        status = np.full((m, n), OUTSIDE, dtype=np.int64)
        scalar_jobs: dict = {}
        profile_jobs: dict = {}
        for k, theta in enumerate(thetas):
            made = self.points(theta)
            # in the order of each kind's first row: the order the points are solved in
            for g in self._profile.groups:
                if made[g][0] is not None:
                    profile_jobs.setdefault(made[g][0], []).append((k, g))
            for g in self._scalar.groups:
                point, material = made[g]
                if point is not None:
                    key = None if material is None else tuple(material.items())
                    scalar_jobs.setdefault(key, []).append((k, g, point))
        if scalar_jobs:
            from ..sweep.arrays import solve

            for key, jobs in scalar_jobs.items():
                # Each distinct point solved once (repeated measurements share it).
                where: dict = {}
                at = [where.setdefault(p, len(where)) for _, _, p in jobs]
                pts = np.array(list(where))
                names = sorted({q for _, g, _ in jobs for q in self._scalar_names[g]})
                ds = solve(*pts.T, material=None if key is None else dict(key), outputs=names,
                           rtol=self.rtol, atol=self.atol, workers=self.workers)
                self.n_solves += int(ds.attrs["n_solves"])
                codes = ds["status"].values
                values = np.stack([ds[q].values for q in names])
                row_of = np.full(self._names.size, -1, dtype=np.intp)
                row_of[np.searchsorted(self._names, names)] = np.arange(len(names))
                for j, (k, g, _) in zip(at, jobs):
                    rows = self._scalar.of(g)
                    status[k, rows] = codes[j]
                    pred[k, rows] = values[row_of[self._scalar.code_of(g)], j]
        if profile_jobs:
            from ..solver.point import solve_point

            for point, jobs in profile_jobs.items():
                xi, local = self._profile_xi([g for _, g in jobs])
                r = solve_point(*point, rtol=self.rtol, atol=self.atol, profile=xi, outputs=[])
                self.n_solves += 1
                values = None if r.profile is None else np.stack(
                    [np.asarray(r.profile[q]) if q in r.profile else np.full(xi.size, math.nan)
                     for q in self._names.tolist()])
                for (k, g), at in zip(jobs, local):
                    rows = self._profile.of(g)
                    status[k, rows] = int(r.status)
                    if values is not None:
                        pred[k, rows] = values[self._profile.code_of(g), at]
        status[(status == 0) & ~np.isfinite(pred)] = NO_VALUE
        return pred, status


class _Rows:
    """Some rows of a table (``rows``, ascending) grouped by their distinct row: those of
    distinct row ``g`` are ``of(g)``, what they measure ``code_of(g)``; ``groups`` are the
    distinct rows that have any, in the order of their first such row."""

    def __init__(self, row_group: np.ndarray, rows: np.ndarray, size: int, code: np.ndarray):
        order = np.argsort(row_group[rows], kind="stable")
        self.rows = rows[order].astype(code.dtype)
        self.group_of = row_group[self.rows]
        self.code = code[self.rows]
        self.count = np.bincount(self.group_of, minlength=size)
        self.start = np.concatenate([[0], np.cumsum(self.count)])
        having = np.flatnonzero(self.count)
        self.groups = having[np.argsort(self.rows[self.start[having]])].tolist()

    def of(self, g: int) -> np.ndarray:
        return self.rows[self.start[g]:self.start[g + 1]]

    def code_of(self, g: int) -> np.ndarray:
        return self.code[self.start[g]:self.start[g + 1]]


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
    pred, status = problem.evaluate(todo)
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
    unresolved: ``sensitivity_flags``); central differences then.

    The rows are taken as a reader of the table would, profile rows first (where the solver
    has no profile sensitivities this gives up at once), then the scalar rows, each in order:
    a point is solved at its first row, and the first row that fails decides the answer and
    ends the solving. Each point's rows are taken together (numpy over them).
    """
    from ..solver import point as point_

    made = problem.points(theta)
    if any(pt is None for pt, _ in made):
        return None, None
    # d (inputs) / d theta of each distinct row by differencing the closed-form map (no solve:
    # exact to ~1e-10).
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
        dinputs.append([_row_derivative(a, b, 2 * h) for a, b in zip(rp, rm)])
    # The rows of each (point, material, kind), and where its first row stands in the order
    # the rows are taken: profile rows first, then scalar rows.
    n_profile = int(problem.profile_rows.sum())
    position = np.empty(problem.data.quantity.size, dtype=np.intp)
    position[problem.profile_rows] = np.arange(n_profile)
    position[~problem.profile_rows] = n_profile + np.arange(position.size - n_profile)
    keys: dict = {}
    for kind, rows in ((True, problem._profile), (False, problem._scalar)):
        for g in rows.groups:
            pt, mat = made[g]
            keys.setdefault((pt, None if mat is None else tuple(mat.items()), kind), []).append(g)
    todo = sorted(keys.items(), key=lambda item: min(
        position[(problem._profile if item[0][2] else problem._scalar).of(g)[0]]
        for g in item[1]))
    J = np.zeros((position.size, p))
    failed = (position.size, None)  # (position of the first row that fails, covered)
    for (pt, mat, kind), groups in todo:
        rows_of = problem._profile if kind else problem._scalar
        if min(position[rows_of.of(g)[0]] for g in groups) > failed[0]:
            break  # its first row comes after the first that fails: never solved
        xi, local = problem._profile_xi(groups) if kind else (None, None)
        r = point_.solve_point(*pt, material=None if mat is None else dict(mat),
                               rtol=problem.rtol, atol=problem.atol, profile=xi,
                               sensitivities=True)
        problem.n_solves += 1
        # The rows' distinct measurements (quantity, group, xi): derivatives are made for
        # those, then given to their rows.
        width = 1 if xi is None else xi.size
        cells = np.concatenate([(rows_of.code_of(g).astype(np.int64) * len(groups) + w) * width
                                + (0 if local is None else local[w])
                                for w, g in enumerate(groups)])
        cells, inverse = np.unique(cells, return_inverse=True)
        cell_code, cell_group = cells // (len(groups) * width), (cells // width) % len(groups)
        cell_xi = cells % width
        JC = np.zeros((cells.size, p))
        fail = np.zeros(cells.size, dtype=np.int8)  # 0, or 1 (not covered), 2 (not finite)
        for c in np.unique(cell_code).tolist():
            at = np.flatnonzero(cell_code == c)
            q = str(problem._names[c])
            if kind:
                sens = {name: np.asarray(v)[cell_xi[at]] for name, v in
                        r.profile_sensitivities.get(q, {}).items()}
            else:
                sens = r.sensitivities.get(q, {})
            for j in range(p):
                total = np.zeros(at.size)
                missing = np.zeros(at.size, dtype=bool)
                for name in dinputs[j][groups[0]]:
                    d = np.array([dinputs[j][g][name] for g in groups])[cell_group[at]]
                    used = d != 0.0
                    if name not in sens:
                        missing |= used
                        continue
                    with np.errstate(invalid="ignore", over="ignore"):
                        total = total + np.where(used, np.asarray(sens[name], dtype=np.float64)
                                                 * d, 0.0)
                fresh = fail[at] == 0
                fail[at[fresh & missing]] = 1
                fail[at[fresh & ~missing & ~np.isfinite(total)]] = 2
                JC[at, j] = total
        rows = np.concatenate([rows_of.of(g) for g in groups])
        J[rows] = JC[inverse.ravel()]
        if fail.any():
            bad = np.flatnonzero(fail[inverse.ravel()])
            k = bad[np.argmin(position[rows[bad]])]
            if position[rows[k]] < failed[0]:
                failed = (position[rows[k]], False if fail[inverse.ravel()[k]] == 1 else None)
    if failed[0] < position.size:
        return None, failed[1]
    return J, True


def _row_derivative(plus, minus, width) -> dict:
    """``{input: d input / d theta_j}`` of one row from its points at ``theta +- h``."""
    (pp, mp), (pm, mm) = plus, minus
    out = {d: (a - b) / width for d, a, b in zip(DIMS, pp, pm)}
    if mp is not None:
        out.update({k: (mp[k] - mm[k]) / width for k in mp})
    return out
