"""The solvers of the work-precision report, each timed over a set of points at one rtol.

- ours: :func:`batch.solve_batch` (both stages) and :func:`batch.stage1_batch` (stage 1), the
  whole set in one kernel call, on one thread, warmed up, best of ``repeat`` calls;
- scipy ``solve_ivp`` (RK45, DOP853, LSODA, Radau): stage 1 alone, point by point in a Python
  loop, in the formulation of ``benchmarks/bench_point.py``'s ``scipy_stage1`` (state
  ``w = delta / xi^2`` from the axis series of :func:`stage1.ivp_start`, the ``D = 0``
  event); Radau and LSODA get the exact Jacobian. One pass (a loop over many points averages
  the noise). A point that needs more than ``max_nfev`` right-hand-side evaluations is abandoned
  (explicit methods need O(1/eta) steps on the stiff points) and counted as failed; the time
  spent on it counts;
- numbalsoda (optional extra ``bench``) LSODA and DOP853: stage 1 alone in a Numba loop through
  numbalsoda's cfunc interface, best of ``repeat``; ``mxstep`` bounds the work per point.

Every runner returns ``(seconds per point, m_wall)`` (stage 1) or ``(seconds per point, dict of
Delta, m_wall, slip)`` (both stages), NaN where a point failed (the scipy loop also the seconds
of each point). All use the same ``atol``.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time

import numpy as np

from ..physics import model
from ..solver import batch, layout, stage1, stage2
from .. import status as st
from .harness import best_of

SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau")
NUMBALSODA_METHODS = ("LSODA", "DOP853")
ATOL = 1e-12


# ---------------------------------------------------------------------------------------------
# Ours
# ---------------------------------------------------------------------------------------------
def ours_both(eps, L, K, A, N, rtol, atol=ATOL, repeat=5):
    """Both stages with ``solve_batch`` (one call for all points); ``(s per point, outputs)``."""
    n = eps.size
    eta = np.ascontiguousarray(eps * L)
    A = np.ascontiguousarray(A, dtype=float)
    N = np.ascontiguousarray(N, dtype=float)
    eps_K = np.ascontiguousarray(eps * K)
    offsets = np.arange(n + 1)
    res = np.empty((n, layout.N_R))
    stats = batch.new_statistics(n, 2)
    one_minus = np.empty(n)
    no_xi = np.empty(0)
    no_prof = np.empty((n, layout.N_PROF, 0))

    def call():
        batch.solve_batch(eta, A, N, eps_K, offsets, rtol, atol, stage1.MAX_STEPS_STAGE1,
                          stage2.MAX_STEPS_STAGE2, res, stats, one_minus, no_xi, no_prof)

    seconds = best_of(call, repeat).seconds
    ok = res[:, layout.R_STATUS] == st.OK
    J = res[:, layout.R_J_AXIS]
    out = {
        "Delta": np.where(ok, one_minus / eps, np.nan),
        "m_wall": np.where(ok, L * res[:, layout.R_MU_WALL], np.nan),
        "slip": np.where(ok, eps_K / (eps_K + J), np.nan),
    }
    return seconds / n, out


def ours_stage1(eps, L, A, N, rtol, atol=ATOL, repeat=5):
    """Stage 1 with ``stage1_batch`` (one call for all points); ``(s per point, m_wall)``."""
    n = eps.size
    eta = np.ascontiguousarray(eps * L)
    A = np.ascontiguousarray(A, dtype=float)
    N = np.ascontiguousarray(N, dtype=float)
    mu = np.empty(n)
    stats = batch.new_statistics(n)

    def call():
        batch.stage1_batch(eta, A, N, rtol, atol, layout.METHOD_AUTO, stage1.MAX_STEPS_STAGE1, mu,
                           stats)

    seconds = best_of(call, repeat).seconds
    return seconds / n, L * mu


def warm_up():
    """Compile or load our kernels outside any timing."""
    one = np.ones(1)
    ours_both(one * 0.03, one * 10.0, one * 0.5, one / 3, one, 1e-6, repeat=1)
    ours_stage1(one * 0.03, one * 10.0, one / 3, one, 1e-6, repeat=1)


# ---------------------------------------------------------------------------------------------
# scipy solve_ivp in a Python loop
# ---------------------------------------------------------------------------------------------
class _BudgetSpent(Exception):
    """The right-hand side was called more than ``max_nfev`` times."""


def scipy_stage1(eps, L, A, N, method, rtol, atol=ATOL, max_nfev=60_000):
    """Stage 1 alone with ``solve_ivp`` (bench_point's formulation); m(1)/nu, NaN on failure."""
    from scipy.integrate import solve_ivp

    eta = eps * L
    if model.classify(eta, A, N) != st.OK:
        return math.nan
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    xi1, w0 = stage1.ivp_start(ax)
    calls = [0]

    def f1(xi, w):
        calls[0] += 1
        if calls[0] > max_nfev:
            raise _BudgetSpent
        return [model.dw_dxi(xi, w[0], eta, A, N, ax)]

    def jac(xi, w):
        return [[model.dw_dxi_jacobian(xi, w[0], eta, A, N, ax)[0]]]

    def hit(xi, w):
        return model.yield_D(xi, xi * xi * w[0], A, N, ax)

    hit.terminal = True
    kw = {"jac": jac} if method in ("Radau", "LSODA", "BDF") else {}
    try:
        with np.errstate(divide="ignore"):  # Radau: see reference.reference
            s1 = solve_ivp(f1, [xi1, 1.0], [w0], method=method, rtol=rtol, atol=atol, events=hit,
                           **kw)
    except _BudgetSpent:
        return math.nan
    return L * (s1.y[0, -1] - N) if s1.status == 0 else math.nan


def scipy_loop(eps, L, A, N, method, rtol, atol=ATOL, max_nfev=60_000):
    """:func:`scipy_stage1` over all points in a Python loop.

    Returns ``(s per point, m_wall, s of each point)``; the last lets the report restrict the
    comparison to the points a method solved without timing it again.
    """
    m = np.empty(eps.size)
    each = np.empty(eps.size)
    for i in range(eps.size):
        t0 = time.perf_counter()
        m[i] = scipy_stage1(eps[i], L[i], A[i], N[i], method, rtol, atol, max_nfev)
        each[i] = time.perf_counter() - t0
    return float(each.mean()) if eps.size else math.nan, m, each


# ---------------------------------------------------------------------------------------------
# numbalsoda (optional)
# ---------------------------------------------------------------------------------------------
def numbalsoda_status():
    """``(module or None, note)``: numbalsoda if it imports, else why not."""
    try:
        import numbalsoda
    except Exception as exc:  # ImportError, or its shared library failing to load
        return None, f"not installed ({type(exc).__name__}: {exc})"
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version("numbalsoda")
    except PackageNotFoundError:
        v = "unknown version"
    return numbalsoda, v


_NBS = {}


def _numbalsoda_kernels(nbs):
    """The cfunc right-hand side (its address) and the Numba loop over points, built once."""
    if _NBS:
        return _NBS["address"], _NBS["loop"]
    from numba import carray, cfunc, njit

    n_data = 3 + model.N_AX
    dw_dxi = model.dw_dxi
    lsoda = nbs.lsoda
    dop853 = nbs.dop853

    @cfunc(nbs.lsoda_sig)
    def rhs(xi, w, dw, p):
        q = carray(p, (n_data,))
        dw[0] = dw_dxi(xi, w[0], q[0], q[1], q[2], q[3:])

    axis_constants = model.axis_constants
    classify = model.classify
    stage1_start = stage1.ivp_start
    OK = st.OK

    @njit
    def loop(address, use_dop853, eta, A, N, rtol, atol, mxstep, mu):
        data = np.empty(n_data)
        t_eval = np.empty(2)
        u0 = np.empty(1)
        for i in range(eta.size):
            mu[i] = np.nan
            if classify(eta[i], A[i], N[i]) != OK:
                continue
            data[0] = eta[i]
            data[1] = A[i]
            data[2] = N[i]
            axis_constants(eta[i], A[i], N[i], data[3:])
            xi1, u0[0] = stage1_start(data[3:])
            t_eval[0] = xi1
            t_eval[1] = 1.0
            if use_dop853:
                usol, success = dop853(address, u0, t_eval, data, rtol, atol, mxstep)
            else:
                usol, success = lsoda(address, u0, t_eval, data, rtol, atol, mxstep)
            if success:
                mu[i] = usol[1, 0] - N[i]

    _NBS["address"] = rhs.address
    _NBS["loop"] = loop
    return rhs.address, loop


def numbalsoda_stage1(nbs, eps, L, A, N, method, rtol, atol=ATOL, repeat=5, mxstep=100_000):
    """Stage 1 with numbalsoda's ``lsoda`` or ``dop853`` in a Numba loop; ``(s per point, m_wall)``."""
    address, loop = _numbalsoda_kernels(nbs)
    eta = np.ascontiguousarray(eps * L)
    A = np.ascontiguousarray(A, dtype=float)
    N = np.ascontiguousarray(N, dtype=float)
    mu = np.empty(eta.size)
    use_dop853 = method == "DOP853"
    with _c_output_discarded():
        loop(address, use_dop853, eta[:1], A[:1], N[:1], rtol, atol, mxstep, mu[:1])  # compile
        seconds = best_of(lambda: loop(address, use_dop853, eta, A, N, rtol, atol, mxstep, mu),
                          repeat).seconds
    return seconds / eta.size, L * mu


@contextlib.contextmanager
def _c_output_discarded():
    """Discard what C code writes to stdout/stderr meanwhile (numbalsoda's solvers print a line
    per failed point, hundreds in a report; the report counts the failures itself)."""
    import ctypes
    import ctypes.util

    flushes = [ctypes.CDLL(None).fflush]  # C stdio
    try:  # numbalsoda's DOP853 is Fortran: its unit 6 has a buffer of its own
        flushes.append(ctypes.CDLL(ctypes.util.find_library("gfortran") or "libgfortran.so.5")
                       ._gfortran_flush_i4)
    except (OSError, AttributeError):
        pass
    sys.stdout.flush()
    sys.stderr.flush()
    saved = (os.dup(1), os.dup(2))
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        for flush in flushes:  # buffers still holding lines for the discarded descriptors
            flush(None)
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
