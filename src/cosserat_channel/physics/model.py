"""The equations of the Cosserat channel-flow model, as Numba scalars.

Source: Mohan, Nott & Rao, "A frictional Cosserat model for the flow of granular materials
through a vertical channel"; the labels (``e-61``, ``eq:56`` ...) are the paper's ``\\label``s and
``docs/model.md`` restates the problem. Nothing here integrates, sweeps or writes files.

Scaled variables
----------------
All stresses are divided by ``rho_p g W nu`` (nu scales out exactly), velocities by the wall spin
``omega_w``. With the exact similarity of model.md, ``eta = eps * L`` and the couple stress is carried
as

    delta = (m + N L) / L = mu + N  >= 0,      mu = m / L,

the cancellation-free state of model.md scaled by ``L``. Stage 1 then reads

    eta d(delta)/d(xi) = (A+1) xi - sqrt(D)                                  (e-61, eq:56, root E-)
    D = (A^2-1) xi^2 + 2(A+1) delta (2N - delta)                             (eq:a3)

and depends on ``(eta, A, N)`` only; ``m = L (delta - N)``. Stage 2 (``e-59``, ``e-60``) uses

    B = -2(A+1) mu / (eta sqrt(D)),    h = (A+1) (1 - (A-1) xi / sqrt(D)).

Near the axis we evaluate ``D`` as ``c0^2 xi^2 + 2(A+1)[2N (delta - y xi^2/2) - delta^2]``, which is the
same polynomial (``c0^2 = A^2 - 1 + 2(A+1) N y``, a consequence of eq:20) but does not subtract two
nearly equal O(xi^2) numbers: ``D`` stays exact to round-off down to ``xi -> 0`` even close to the
axis edge where ``c0 -> 0``.
"""

from __future__ import annotations

import math

from numba import njit
from .._jit import EPS as _EPS, JIT as _JIT, JIT_INLINE as _JIT_INLINE

from . import analytic



# Slots of the axis-constants array returned by `axis_constants`.
AX_Y = 0  # mu''(0) = x / L, the curvature of the axis series (eq:20)
AX_C0 = 1  # sqrt(D)/xi at the axis, = A + 1 - eta*y
AX_K = 2  # fourth-order coefficient of the axis series of delta
AX_BETA = 3  # B ~ beta / xi near the axis (Appendix B)
AX_NMAX = 4  # how many terms axis_series computed
AX_NW = 5  # how many of them are used (series_reach)
AX_N2 = 6  # how many terms stage2_series computed
AX_W = 7  # w = delta / xi^2 = sum_k ax[AX_W + k] xi^(2k), k < AX_NW (axis_series)
N_SERIES = 40  # at most this many terms
AX_S = AX_W + N_SERIES  # sqrt(D) / xi = sum_k ax[AX_S + k] xi^(2k), the companion series
AX_G = AX_S + N_SERIES  # int B dxi = beta ln(xi) + sum_k ax[AX_G + k] xi^(2k)   (stage2_series)
AX_F = AX_G + N_SERIES  # int_0^xi h omega_hat = c xi^(beta+1) sum_k ax[AX_F + k] xi^(2k)
AX_R = AX_F + N_SERIES  # scratch: 1/S
AX_E = AX_R + N_SERIES  # scratch: exp(G)
N_AX = AX_E + N_SERIES
# The w series stops once its terms are below this (relative to w(0)) at xi = 1: they cannot
# matter anywhere stage 1 reads it.
SERIES_NEGLIGIBLE = 1e-18


# --------------------------------------------------------------------------------------------
# Regimes (Appendix A) and the axis condition (eq:20)
# --------------------------------------------------------------------------------------------
# The plain-Python originals live in analytic.py (the atlas classifies without numba); these are
# their compiled copies for the kernels.
axis_margin = njit(**_JIT)(analytic.axis_margin)
_classify_margin = njit(**_JIT)(analytic.classify_margin)


@njit(**_JIT)
def classify(eta, A, N):
    """Status decided before any integration, for the regimes of Appendix A.

    Returns ``OK`` when stage 1 must be integrated (A > -1, axis series admissible) or when the
    A = -1 closed form applies (:func:`cosserat_channel.physics.analytic.classify_margin`).
    """
    return _classify_margin(axis_margin(eta, A, N), A, N)


@njit(**_JIT)
def axis_constants(eta, A, N, out):
    """Fill ``out[N_AX]`` with the axis series of eq:20 in cancellation-free form (A > -1).

    ``y = mu''(0)`` is the smaller root of ``eta^2 y^2 - 2(A+1)(eta+N) y + 2(A+1) = 0`` (eq:20 with
    ``x = L y``), written as ``y = 2(A+1) / [(A+1)(eta+N) + s]``. ``c0 = A + 1 - eta y`` equals
    ``(A+1) g / (s + (A+1) N)`` with ``g`` the axis margin, so it needs no subtraction. The quartic
    term ``k xi^4`` follows from e-61 at the next order. Requires ``axis_margin >= 0``.
    """
    a1 = A + 1.0
    s = math.sqrt(a1 * a1 * (eta + N) * (eta + N) - 2.0 * a1 * eta * eta)
    y = 2.0 * a1 / (a1 * (eta + N) + s)
    c0 = a1 * axis_margin(eta, A, N) / (s + a1 * N)
    out[AX_Y] = y
    out[AX_C0] = c0
    out[AX_K] = a1 * y * y / (4.0 * (4.0 * eta * c0 + 2.0 * a1 * N))
    out[AX_BETA] = 2.0 * a1 * N / (eta * c0) if c0 > 0.0 else math.inf
    axis_series(eta, A, N, out)


@njit(**_JIT)
def axis_series(eta, A, N, ax):
    """The power series of ``w = delta/xi^2`` at the axis, to up to ``N_SERIES`` terms in ``xi^2``.

    The axis is a regular singular point of stage 1, and its solution is analytic there: with
    ``x = xi^2``, ``w = sum_k d_k x^k`` and ``sqrt(D)/xi = S = sum_j s_j x^j`` (``s_0 = c0``),
    e-61 gives ``d_0 = y/2`` and ``2 (m+1) eta d_m = -s_m`` for ``m >= 1``. ``S^2 = D/xi^2``
    (eq:a3) at order ``x^m`` holds ``d_m`` linearly (in ``4(A+1)N d_m``); with the first relation
    it is linear in ``s_m``:

        s_m (2 c0 + 2(A+1)N / ((m+1) eta)) = -2(A+1) sum_{i+l=m-1} d_i d_l - sum_{0<j<m} s_j s_{m-j},

    whose right-hand side needs only ``d`` and ``s`` of lower index. The divisor is positive, so the recursion is
    stable; its terms shrink geometrically inside the radius of convergence, which is set by the
    nearest singularity of the path (D = 0 or the outer solution's branch point near ``xi = N``).
    Stage 1 starts its march where the series stops being accurate (:func:`series_reach`) instead
    of next to the axis, where an ODE solver must take geometric steps in xi. Fills ``AX_NW``,
    ``AX_W...`` and ``AX_S...`` of ``ax``; needs ``AX_Y`` and ``AX_C0`` (:func:`axis_constants`).
    """
    a1 = A + 1.0
    c0 = ax[AX_C0]
    ax[AX_W] = 0.5 * ax[AX_Y]
    ax[AX_S] = c0
    n = N_SERIES
    small = SERIES_NEGLIGIBLE * abs(ax[AX_W])
    for m in range(1, N_SERIES):
        acc = _convolve(ax, AX_W, AX_W, 0, m, m - 1)  # sum_{i+l=m-1} d_i d_l
        acc2 = _convolve(ax, AX_S, AX_S, 1, m, m)  # sum_{0<j<m} s_j s_{m-j}
        s_m = (-2.0 * a1 * acc - acc2) / (2.0 * c0 + 2.0 * a1 * N / ((m + 1) * eta))
        ax[AX_S + m] = s_m
        ax[AX_W + m] = -s_m / (2.0 * (m + 1) * eta)
        if abs(ax[AX_W + m]) < small and abs(ax[AX_W + m - 1]) < small:
            n = m + 1
            break
    ax[AX_NMAX] = n
    ax[AX_NW] = n


@njit(**_JIT_INLINE)
def w_axis_series(xi, ax):
    """``w = delta / xi^2`` from the axis series (:func:`axis_series`), by Horner in ``xi^2``."""
    return _horner(ax, AX_W, int(ax[AX_NW]), xi * xi)


@njit(**_JIT)
def stage2_series(eta, A, N, ax):
    """Stage 2 below the reach of the axis series, in closed form: fills ``AX_G`` and ``AX_F``.

    With ``x = xi^2``, ``1/S`` (``S = sqrt(D)/xi``), ``xi B = 2(A+1)(N - x w)/(eta S) = beta +
    sum_k p_k x^k`` (e-60) and ``h = (A+1)(1 - (A-1)/S)`` (e-59) are power series, so

        log omega_hat(xi) = const + beta ln(xi) + G(x),            G = sum_k p_k x^k / (2k),
        int_0^xi h omega_hat dxi' = c xi^(beta+1) F(x),           F = sum_k H_k x^k / (beta+1+2k),

    with ``H = h exp(G)`` and ``c`` fixed by omega_hat at one point (``stage2._series_log_I``).
    Each series costs one Cauchy product; ``exp(G)`` follows from ``x E' = x G' E``. Needs
    :func:`axis_series` and :func:`series_reach` (``AX_NW``); sets ``AX_N2``.
    """
    # A few more terms than w needs where the march starts: these series converge alike.
    n = min(int(ax[AX_NMAX]), int(ax[AX_NW]) + 6)
    ax[AX_N2] = n
    a1 = A + 1.0
    c = 2.0 * a1 / eta
    beta = ax[AX_BETA]
    ax[AX_R] = 1.0 / ax[AX_S]
    ax[AX_G] = 0.0
    ax[AX_E] = 1.0
    ax[AX_F] = a1 * (ax[AX_E] - (A - 1.0) * _convolve(ax, AX_R, AX_E, 0, 1, 0)) / (beta + 1.0)
    # Term m of each series needs terms up to m of the ones before it: one loop over m, so that
    # the two chains of dependent terms (1/S and exp(G)) wait on their sums side by side.
    for m in range(1, n):
        # 1/S's and xi B's sums read the same terms of 1/S: one pass over them
        sr, wr = _convolve_pair(ax, AX_S, AX_W - 1, AX_R, 1, m + 1, m)
        ax[AX_R + m] = -sr * ax[AX_R]
        p = N * ax[AX_R + m] - wr
        ax[AX_G + m] = c * p / (2.0 * m)
        # exp(G): m E_m = sum_k (k g_k) E_(m-k)
        ax[AX_E + m] = _convolve(ax, AX_G, AX_E, 1, m + 1, m, True) / m
        conv = _convolve(ax, AX_R, AX_E, 0, m + 1, m)
        ax[AX_F + m] = a1 * (ax[AX_E + m] - (A - 1.0) * conv) / (beta + 1.0 + 2.0 * m)


@njit(**_JIT_INLINE)
def _convolve(ax, a, b, j0, j1, m, weighted=False):
    """``sum_{j0 <= j < j1} ax[a + j] ax[b + m - j]``, in four independent sums (the latency of
    one chain of additions, not the arithmetic, is what a Cauchy product of 40 terms waits on);
    ``weighted``: with ``j ax[a + j]`` for ``ax[a + j]``."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    j = j0
    if weighted:
        while j + 3 < j1:
            s0 += (j * ax[a + j]) * ax[b + m - j]
            s1 += ((j + 1) * ax[a + j + 1]) * ax[b + m - j - 1]
            s2 += ((j + 2) * ax[a + j + 2]) * ax[b + m - j - 2]
            s3 += ((j + 3) * ax[a + j + 3]) * ax[b + m - j - 3]
            j += 4
        while j < j1:
            s0 += (j * ax[a + j]) * ax[b + m - j]
            j += 1
        return (s0 + s1) + (s2 + s3)
    while j + 3 < j1:
        s0 += ax[a + j] * ax[b + m - j]
        s1 += ax[a + j + 1] * ax[b + m - j - 1]
        s2 += ax[a + j + 2] * ax[b + m - j - 2]
        s3 += ax[a + j + 3] * ax[b + m - j - 3]
        j += 4
    while j < j1:
        s0 += ax[a + j] * ax[b + m - j]
        j += 1
    return (s0 + s1) + (s2 + s3)


@njit(**_JIT_INLINE)
def _convolve_pair(ax, a, a2, b, j0, j1, m):
    """``(_convolve(ax, a, b, j0, j1, m), _convolve(ax, a2, b, j0, j1, m))`` in one pass: each
    term of ``b`` is loaded once for both, and each sum adds the same products in the same order
    as :func:`_convolve` (same bits)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    t3 = 0.0
    j = j0
    while j + 3 < j1:
        b0 = ax[b + m - j]
        b1 = ax[b + m - j - 1]
        b2 = ax[b + m - j - 2]
        b3 = ax[b + m - j - 3]
        s0 += ax[a + j] * b0
        s1 += ax[a + j + 1] * b1
        s2 += ax[a + j + 2] * b2
        s3 += ax[a + j + 3] * b3
        t0 += ax[a2 + j] * b0
        t1 += ax[a2 + j + 1] * b1
        t2 += ax[a2 + j + 2] * b2
        t3 += ax[a2 + j + 3] * b3
        j += 4
    while j < j1:
        b0 = ax[b + m - j]
        s0 += ax[a + j] * b0
        t0 += ax[a2 + j] * b0
        j += 1
    return (s0 + s1) + (s2 + s3), (t0 + t1) + (t2 + t3)


@njit(**_JIT_INLINE)
def _horner(ax, start, n, x):
    acc = ax[start + n - 1]
    for k in range(n - 2, -1, -1):
        acc = acc * x + ax[start + k]
    return acc


@njit(**_JIT_INLINE)
def _series_good(ax, start, n, x, tol, floor):
    """Whether the ``n``-term series in slots ``start...`` is good to ``tol`` at ``x``.

    Its tail is estimated from the geometric decay of the kept terms: ``rho``, the largest ratio
    ``|c_k / c_(k-1)|`` among the last eight, estimates ``1/radius``, and the tail is below ``T rho
    x / (1 - rho x)``, with ``T`` the largest of the last four terms at ``x``; ``x`` must stay below
    ``0.8/rho``, well inside the radius. The tail and the rounding (``1e-16`` times the sum of the
    terms' sizes, which catches cancelling terms) must be below ``tol * max(|sum|, floor)``.
    """
    # A series whose terms vanished (axis_series stopped early) is a polynomial: no tail.
    complete = n == int(ax[AX_NMAX]) and n < N_SERIES
    rho = 0.0
    for k in range(max(1, n - 8), n):
        prev = abs(ax[start + k - 1])
        if prev > 0.0:
            rho = max(rho, abs(ax[start + k]) / prev)
    if not (complete or rho * x < 0.8):
        return False
    total = 0.0
    size = 0.0
    last = 0.0
    xk = 1.0
    for k in range(n):
        term = ax[start + k] * xk
        total += term
        size += abs(term)
        if k >= n - 4:
            last = max(last, abs(term))
        xk *= x
    tail = last if complete else last * rho * x / (1.0 - rho * x)
    return tail + 1e-16 * size <= tol * max(abs(total), floor)


@njit(**_JIT)
def stage2_series_reach(ax, tol, xi_max):
    """How far from the axis :func:`stage2_series` is good to ``tol`` (``G`` absolutely, ``F``
    relatively): ``xi`` in ``(0, xi_max]``, shrunk by 0.8 from ``xi_max``; 0 when none."""
    n = int(ax[AX_N2])
    x = xi_max * xi_max
    for _ in range(60):
        if (_series_good(ax, AX_G, n, x, tol, 1.0) and _series_good(ax, AX_F, n, x, tol, 0.0)
                and _positive(ax, AX_F, n, x)):
            # keep only the terms that matter there (the plug-edge root evaluates F many times)
            ax[AX_N2] = max(_terms_needed(ax, AX_G, n, x, 0.1 * tol),
                            _terms_needed(ax, AX_F, n, x, 0.1 * tol))
            return math.sqrt(x)
        x *= 0.64
    return 0.0


@njit(**_JIT)
def series_G(xi, ax):
    """``G(xi^2)`` of :func:`stage2_series`: ``log omega_hat - beta ln(xi)`` up to a constant."""
    return _horner(ax, AX_G, int(ax[AX_N2]), xi * xi)


@njit(**_JIT)
def series_F(xi, ax):
    """``F(xi^2)`` of :func:`stage2_series`."""
    return _horner(ax, AX_F, int(ax[AX_N2]), xi * xi)


@njit(**_JIT)
def series_F_dF(x, ax):
    """``(F(x), dF/dx)`` of :func:`stage2_series` at ``x = xi^2``, in one Horner pass."""
    n = int(ax[AX_N2])
    F = ax[AX_F + n - 1]
    dF = 0.0
    for k in range(n - 2, -1, -1):
        dF = dF * x + F
        F = F * x + ax[AX_F + k]
    return F, dF


@njit(**_JIT)
def series_reach(ax, tol, xi_max):
    """How far from the axis the w series is good to ``tol`` (relative): ``xi`` in ``(0, xi_max]``.

    Starting at ``xi_max``, ``xi^2`` shrinks by 0.7 until :func:`_series_good` accepts the series
    there and ``sqrt(D)/xi`` is positive at 16 points up to it (the path has not met D = 0).
    Then keeps (``AX_NW``) only the terms that matter there: the dropped ones add at most
    ``tol/10``. Returns 0 when no ``xi`` qualifies.
    """
    n = int(ax[AX_NMAX])
    x = xi_max * xi_max
    for _ in range(100):
        if not x > 1e-300:
            break
        if _series_good(ax, AX_W, n, x, tol, 0.0) and _positive(ax, AX_S, n, x):
            ax[AX_NW] = _terms_needed(ax, AX_W, n, x, 0.1 * tol)
            return math.sqrt(x)
        x *= 0.7
    ax[AX_NW] = n
    return 0.0


@njit(**_JIT_INLINE)
def _terms_needed(ax, start, n, x, tol):
    """The fewest leading terms of the series in slots ``start...`` whose dropped rest, summed in
    size at ``x``, is below ``tol`` times the sum."""
    total = abs(_horner(ax, start, n, x))
    # x^k for k = n-1, n-2, ...: one power, then a division per term (a power per term cost
    # more than the rest of the loop); either is within a few ulps of x^k, which moves the
    # comparison below only at a tie within rounding
    xk = x ** (n - 1)
    dropped = 0.0
    k = n - 1
    while k > 1:
        size = abs(ax[start + k]) * xk
        if dropped + size > tol * total:
            break
        dropped += size
        xk /= x
        k -= 1
    return k + 1


@njit(**_JIT_INLINE)
def _positive(ax, start, n, x_end):
    """The series in slots ``start...`` is positive at 16 points of ``(0, x_end]``.

    Horner's sums at four points at a time: each is a chain of dependent multiply-adds, and four
    independent chains run in the latency of one (the same sums, so the same verdict).

    First a test in one pass that implies that verdict: where the leading term exceeds the rest in
    size at ``x_end``, ``c_0 - sum_(k>0) |c_k| x_end^k > 16 n EPS (c_0 + sum_(k>0) |c_k| x_end^k)``,
    the series is positive on all of ``(0, x_end]`` with a margin above Horner's rounding
    (``< 2 n EPS`` times the terms' sizes) and that of the test's own sums, so every one of the 16
    sums is positive too.
    """
    lead = ax[start]
    rest = 0.0
    xk = 1.0
    for k in range(1, n):
        xk *= x_end
        rest += abs(ax[start + k]) * xk
    if lead - rest > 16.0 * n * _EPS * (lead + rest):
        return True
    for i in range(1, 17, 4):
        x0 = x_end * i / 16.0
        x1 = x_end * (i + 1) / 16.0
        x2 = x_end * (i + 2) / 16.0
        x3 = x_end * (i + 3) / 16.0
        top = ax[start + n - 1]
        a0 = top
        a1 = top
        a2 = top
        a3 = top
        for k in range(n - 2, -1, -1):
            c = ax[start + k]
            a0 = a0 * x0 + c
            a1 = a1 * x1 + c
            a2 = a2 * x2 + c
            a3 = a3 * x3 + c
        if not (a0 > 0.0 and a1 > 0.0 and a2 > 0.0 and a3 > 0.0):
            return False
    return True


@njit(**_JIT_INLINE)
def axis_relative_margin(A, N, ax):
    """``c0^2`` relative to the terms of ``D/xi^2`` at the axis that it is the difference of.

    ``c0^2 = (A^2 - 1) + 2(A+1) N y``: the two terms are ``O(A+1)``, so the number of digits ``D``
    keeps next to the axis is set by ``c0^2 / (2(A+1) N y)``, not by ``c0^2`` alone. The two differ
    when ``A -> -1``, where ``c0 ~ A + 1`` far from the axis edge (found by the domain tests: the
    bare ``c0^2`` treated every point with ``A + 1 < 1e-5`` as if it sat on the axis edge).
    """
    return ax[AX_C0] * ax[AX_C0] / (2.0 * (A + 1.0) * N * ax[AX_Y])


@njit(**_JIT)
def delta_axis_series(xi, ax):
    """``delta`` near the axis: ``m = -N L + x xi^2 / 2`` (eq:54, eq:20) and the higher terms of
    :func:`axis_series`."""
    return xi * xi * w_axis_series(xi, ax)


# --------------------------------------------------------------------------------------------
# Stage 1: stresses, xi = 0 -> 1
# --------------------------------------------------------------------------------------------
@njit(**_JIT_INLINE)
def yield_D(xi, delta, A, N, ax):
    """``D`` under the square root of eq:56 / eq:a3 (scaled), evaluated cancellation-free."""
    r = delta - 0.5 * ax[AX_Y] * xi * xi
    c0xi = ax[AX_C0] * xi
    return c0xi * c0xi + 2.0 * (A + 1.0) * (2.0 * N * r - delta * delta)


@njit(**_JIT_INLINE)
def yield_D_rounding(xi, delta, A, N, ax):
    """A bound on the rounding error of :func:`yield_D`: a few ulps of the terms it sums (and of
    ``delta`` carried through them). Large against ``D`` only where ``D`` is a small difference."""
    return _EPS * (ax[AX_C0] * ax[AX_C0] * xi * xi + abs(2.0 * (A + 1.0)) * (
        2.0 * N * (abs(delta) + abs(ax[AX_Y]) * xi * xi) + 3.0 * delta * delta))


@njit(**_JIT)
def ddelta_dxi(xi, delta, eta, A, N, ax):
    """Stage-1 right-hand side, e-61 with eq:56 (root ``E-`` of eq:a2): ``eta delta' = (A+1) xi - sqrt(D)``.

    ``D`` is clipped at 0: a trial RK stage may step just outside the admissible region, and the
    ``D = 0`` event (not a NaN) is what reports that the path left it.
    """
    D = yield_D(xi, delta, A, N, ax)
    return ((A + 1.0) * xi - math.sqrt(max(D, 0.0))) / eta


@njit(**_JIT)
def dw_dxi(xi, w, eta, A, N, ax):
    """Stage 1 for the integrator, in ``w = delta / xi^2``: ``w' = (delta' - 2 xi w) / xi^2``.

    ``delta`` grows like ``xi^2`` off the axis, so a relative error control on ``delta`` forces
    geometric steps there (about 230 of them at eta = 1/3, rtol = 1e-8); ``w = y/2 + k xi^2 + ...``
    is smooth and O(1), which leaves only the stability limit ``h < 3.3 xi / (beta + 2)``.
    """
    delta = xi * xi * w
    return (ddelta_dxi(xi, delta, eta, A, N, ax) - 2.0 * xi * w) / (xi * xi)


@njit(**_JIT)
def dw_dxi_jacobian(xi, w, eta, A, N, ax):
    """Exact ``(d f/d w, d f/d xi)`` of :func:`dw_dxi` ``= f(xi, w)``, for the Rosenbrock path.

    With ``g(xi, delta) = ((A+1) xi - sqrt(D))/eta`` and ``delta = xi^2 w``:
    ``df/dw = g_delta - 2/xi = -B - 2/xi`` (model.md: the stage-1 Jacobian is ``-B``), and
    ``df/dxi = (g_xi + 2 xi w g_delta - 2w)/xi^2 - 2 (g - 2 xi w)/xi^3`` with
    ``g_xi = ((A+1) - (A^2-1) xi / sqrt(D))/eta``.
    """
    delta = xi * xi * w
    D = yield_D(xi, delta, A, N, ax)
    sq = math.sqrt(max(D, 1e-300))
    g = ((A + 1.0) * xi - sq) / eta
    g_delta = -2.0 * (A + 1.0) * (N - delta) / (eta * sq)
    g_xi = ((A + 1.0) - (A * A - 1.0) * xi / sq) / eta
    dfdw = g_delta - 2.0 / xi
    dfdxi = (g_xi + 2.0 * xi * w * g_delta - 2.0 * w) / (xi * xi) - 2.0 * (g - 2.0 * xi * w) / (xi * xi * xi)
    return dfdw, dfdxi


@njit(**_JIT)
def sigma_xy(xi):
    """eq:19: ``sigma_xy = -xi`` (scaled by nu)."""
    return -xi


@njit(**_JIT_INLINE)
def sigma_yx(xi, D, A):
    """eq:56 with the root the paper keeps: ``sigma_yx = A xi - sqrt(D)`` (scaled by nu)."""
    return A * xi - math.sqrt(max(D, 0.0))


# --------------------------------------------------------------------------------------------
# Stage 2: velocities, xi = 1 -> 0
# --------------------------------------------------------------------------------------------
@njit(**_JIT_INLINE)
def spin_rate_B(delta, inv_sqrt_D, eta, A, N):
    """``B`` of eq:18 / e-60, ``d omega/d xi = B omega``; with ``s = sigma_yx + A sigma_xy = -sqrt(D)``,
    given as ``inv_sqrt_D = 1/sqrt(D)`` (stage 2 needs it for ``h`` too: one root, one division).

    Also minus the Jacobian of the stage-1 right-hand side with respect to ``delta`` (model.md).
    """
    # the factor 2(A + 1)/eta is the same at every node: written first, it is computed once
    return 2.0 * (A + 1.0) / eta * ((N - delta) * inv_sqrt_D)


@njit(**_JIT_INLINE)
def shear_rate_h(xi, inv_sqrt_D, A):
    """``h`` of e-59: ``du/d xi = -h omega``; ``inv_sqrt_D = 1/sqrt(D)`` as in :func:`spin_rate_B`."""
    return (A + 1.0) * (1.0 - (A - 1.0) * xi * inv_sqrt_D)


@njit(**_JIT)
def plug_target(J_axis, eps_K):
    """Right-hand side of eq:13 in terms of ``J``: ``J(xi_p) = 0.95 J(0) - 0.05 eps K``.

    ``u(xi)/omega_w = eps K + J(xi)`` (eq:7), so ``u(xi_p) = 0.95 u(0)`` is this. Negative or zero
    means the wall already moves at >= 95 % of the centre: ``xi_p = 1`` and ``Delta = 0``.
    """
    return 0.95 * J_axis - 0.05 * eps_K


# --------------------------------------------------------------------------------------------
# A = -1 (Appendix A): closed form
# --------------------------------------------------------------------------------------------
@njit(**_JIT_INLINE)
def a_minus_one_xi_B(eta, N):
    """``xi B = c = 2N/eta`` for A = -1: the limit of e-60 on ``m = -N L``, where ``D = 0``."""
    return 2.0 * N / eta


@njit(**_JIT_INLINE)
def a_minus_one_h():
    """``h = 2`` for A = -1: Appendix A's ``du/dxi = -2 omega`` (e-59 with sigma_yx = -xi)."""
    return 2.0
