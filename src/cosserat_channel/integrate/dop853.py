"""Adaptive Dormand–Prince 8(5,3) (Hairer's ``DOP853``) written for Numba, with its 7th-order
dense output.

The same calling convention as :func:`.rk45.dopri5` (right-hand side, terminal event, step
budget, counters, outcome codes) and the same driver loop (:func:`.explicit.explicit_rk`, given
this module's step, error norm, controller and dense output), so that a caller can pick either
by tolerance: the integrator knows nothing about the physics. Each accepted step stores its dense output in Hairer's
``CONTD8`` layout, which extends ``CONTD5``'s nesting by three rows (:mod:`.dense`), so one
evaluation formula reads both.

Per step: 12 stages (the 13th, ``f(t + h, y_new)``, is the next step's first: FSAL) and 3 more
for the dense output. The error estimate is Hairer's blend of a 5th- and a 3rd-order embedded
solution, ``|h| err5^2 / sqrt(err5^2 + 0.01 err3^2)``, which behaves like an 8th-order one;
step sizes follow it with exponent 1/8 (scipy's controller: safety 0.9, factors in [0.2, 10]).
After each accepted step Hairer's stiffness test (``|h lambda|`` beyond 6.1, DOP853's real
stability boundary) counts into the same counters as Dormand-Prince's
(:func:`.stepping.count_stiffness`), and its ``|lambda|`` estimate bounds the next step: one
that passes the error test beyond 1.5 times the boundary is rejected all the same
(:func:`.stepping.beyond_stability`; the error estimate vanishes out there).

Why it is here: on stage 1 it takes about as many evaluations as Dormand–Prince 5(4) at the
same rtol and is 20-40x more accurate (``benchmarks/probes/probe_high_order.py``), so at a matched
error it is several times cheaper; :mod:`cosserat_channel.solver.stage1` uses it for tight tolerances.

The coefficients are Hairer's, as transcribed in scipy's ``integrate/_ivp/dop853_coefficients.py``
(BSD-3-Clause, copied here so that the kernels do not depend on a private scipy module).

References
----------
.. [HNW93] E. Hairer, S. P. Nørsett and G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer (1993); Sec. II.10 (DOP853), II.6 (dense output).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from .dense import hermite_rows
from .explicit import explicit_rk
from .stepping import NONFINITE_SHRINK

__all__ = ["dop853", "dop853_step", "ERROR_ORDER"]

# ---------------------------------------------------------------------------------------------
# Tableau (Hairer's dop853.f, via scipy; see the module docstring)
# ---------------------------------------------------------------------------------------------
N_STAGES = 12
N_STAGES_EXTENDED = 16
INTERPOLATOR_POWER = 7

C = np.array([0.0,
              0.526001519587677318785587544488e-01,
              0.789002279381515978178381316732e-01,
              0.118350341907227396726757197510,
              0.281649658092772603273242802490,
              0.333333333333333333333333333333,
              0.25,
              0.307692307692307692307692307692,
              0.651282051282051282051282051282,
              0.6,
              0.857142857142857142857142857142,
              1.0,
              1.0,
              0.1,
              0.2,
              0.777777777777777777777777777778])

A = np.zeros((N_STAGES_EXTENDED, N_STAGES_EXTENDED))
A[1, 0] = 5.26001519587677318785587544488e-2

A[2, 0] = 1.97250569845378994544595329183e-2
A[2, 1] = 5.91751709536136983633785987549e-2

A[3, 0] = 2.95875854768068491816892993775e-2
A[3, 2] = 8.87627564304205475450678981324e-2

A[4, 0] = 2.41365134159266685502369798665e-1
A[4, 2] = -8.84549479328286085344864962717e-1
A[4, 3] = 9.24834003261792003115737966543e-1

A[5, 0] = 3.7037037037037037037037037037e-2
A[5, 3] = 1.70828608729473871279604482173e-1
A[5, 4] = 1.25467687566822425016691814123e-1

A[6, 0] = 3.7109375e-2
A[6, 3] = 1.70252211019544039314978060272e-1
A[6, 4] = 6.02165389804559606850219397283e-2
A[6, 5] = -1.7578125e-2

A[7, 0] = 3.70920001185047927108779319836e-2
A[7, 3] = 1.70383925712239993810214054705e-1
A[7, 4] = 1.07262030446373284651809199168e-1
A[7, 5] = -1.53194377486244017527936158236e-2
A[7, 6] = 8.27378916381402288758473766002e-3

A[8, 0] = 6.24110958716075717114429577812e-1
A[8, 3] = -3.36089262944694129406857109825
A[8, 4] = -8.68219346841726006818189891453e-1
A[8, 5] = 2.75920996994467083049415600797e1
A[8, 6] = 2.01540675504778934086186788979e1
A[8, 7] = -4.34898841810699588477366255144e1

A[9, 0] = 4.77662536438264365890433908527e-1
A[9, 3] = -2.48811461997166764192642586468
A[9, 4] = -5.90290826836842996371446475743e-1
A[9, 5] = 2.12300514481811942347288949897e1
A[9, 6] = 1.52792336328824235832596922938e1
A[9, 7] = -3.32882109689848629194453265587e1
A[9, 8] = -2.03312017085086261358222928593e-2

A[10, 0] = -9.3714243008598732571704021658e-1
A[10, 3] = 5.18637242884406370830023853209
A[10, 4] = 1.09143734899672957818500254654
A[10, 5] = -8.14978701074692612513997267357
A[10, 6] = -1.85200656599969598641566180701e1
A[10, 7] = 2.27394870993505042818970056734e1
A[10, 8] = 2.49360555267965238987089396762
A[10, 9] = -3.0467644718982195003823669022

A[11, 0] = 2.27331014751653820792359768449
A[11, 3] = -1.05344954667372501984066689879e1
A[11, 4] = -2.00087205822486249909675718444
A[11, 5] = -1.79589318631187989172765950534e1
A[11, 6] = 2.79488845294199600508499808837e1
A[11, 7] = -2.85899827713502369474065508674
A[11, 8] = -8.87285693353062954433549289258
A[11, 9] = 1.23605671757943030647266201528e1
A[11, 10] = 6.43392746015763530355970484046e-1

A[12, 0] = 5.42937341165687622380535766363e-2
A[12, 5] = 4.45031289275240888144113950566
A[12, 6] = 1.89151789931450038304281599044
A[12, 7] = -5.8012039600105847814672114227
A[12, 8] = 3.1116436695781989440891606237e-1
A[12, 9] = -1.52160949662516078556178806805e-1
A[12, 10] = 2.01365400804030348374776537501e-1
A[12, 11] = 4.47106157277725905176885569043e-2

A[13, 0] = 5.61675022830479523392909219681e-2
A[13, 6] = 2.53500210216624811088794765333e-1
A[13, 7] = -2.46239037470802489917441475441e-1
A[13, 8] = -1.24191423263816360469010140626e-1
A[13, 9] = 1.5329179827876569731206322685e-1
A[13, 10] = 8.20105229563468988491666602057e-3
A[13, 11] = 7.56789766054569976138603589584e-3
A[13, 12] = -8.298e-3

A[14, 0] = 3.18346481635021405060768473261e-2
A[14, 5] = 2.83009096723667755288322961402e-2
A[14, 6] = 5.35419883074385676223797384372e-2
A[14, 7] = -5.49237485713909884646569340306e-2
A[14, 10] = -1.08347328697249322858509316994e-4
A[14, 11] = 3.82571090835658412954920192323e-4
A[14, 12] = -3.40465008687404560802977114492e-4
A[14, 13] = 1.41312443674632500278074618366e-1

A[15, 0] = -4.28896301583791923408573538692e-1
A[15, 5] = -4.69762141536116384314449447206
A[15, 6] = 7.68342119606259904184240953878
A[15, 7] = 4.06898981839711007970213554331
A[15, 8] = 3.56727187455281109270669543021e-1
A[15, 12] = -1.39902416515901462129418009734e-3
A[15, 13] = 2.9475147891527723389556272149
A[15, 14] = -9.15095847217987001081870187138


B = A[N_STAGES, :N_STAGES]

E3 = np.zeros(N_STAGES + 1)
E3[:-1] = B.copy()
E3[0] -= 0.244094488188976377952755905512
E3[8] -= 0.733846688281611857341361741547
E3[11] -= 0.220588235294117647058823529412e-1

E5 = np.zeros(N_STAGES + 1)
E5[0] = 0.1312004499419488073250102996e-1
E5[5] = -0.1225156446376204440720569753e+1
E5[6] = -0.4957589496572501915214079952
E5[7] = 0.1664377182454986536961530415e+1
E5[8] = -0.3503288487499736816886487290
E5[9] = 0.3341791187130174790297318841
E5[10] = 0.8192320648511571246570742613e-1
E5[11] = -0.2235530786388629525884427845e-1

# First 3 coefficients are computed separately.
D = np.zeros((INTERPOLATOR_POWER - 3, N_STAGES_EXTENDED))
D[0, 0] = -0.84289382761090128651353491142e+1
D[0, 5] = 0.56671495351937776962531783590
D[0, 6] = -0.30689499459498916912797304727e+1
D[0, 7] = 0.23846676565120698287728149680e+1
D[0, 8] = 0.21170345824450282767155149946e+1
D[0, 9] = -0.87139158377797299206789907490
D[0, 10] = 0.22404374302607882758541771650e+1
D[0, 11] = 0.63157877876946881815570249290
D[0, 12] = -0.88990336451333310820698117400e-1
D[0, 13] = 0.18148505520854727256656404962e+2
D[0, 14] = -0.91946323924783554000451984436e+1
D[0, 15] = -0.44360363875948939664310572000e+1

D[1, 0] = 0.10427508642579134603413151009e+2
D[1, 5] = 0.24228349177525818288430175319e+3
D[1, 6] = 0.16520045171727028198505394887e+3
D[1, 7] = -0.37454675472269020279518312152e+3
D[1, 8] = -0.22113666853125306036270938578e+2
D[1, 9] = 0.77334326684722638389603898808e+1
D[1, 10] = -0.30674084731089398182061213626e+2
D[1, 11] = -0.93321305264302278729567221706e+1
D[1, 12] = 0.15697238121770843886131091075e+2
D[1, 13] = -0.31139403219565177677282850411e+2
D[1, 14] = -0.93529243588444783865713862664e+1
D[1, 15] = 0.35816841486394083752465898540e+2

D[2, 0] = 0.19985053242002433820987653617e+2
D[2, 5] = -0.38703730874935176555105901742e+3
D[2, 6] = -0.18917813819516756882830838328e+3
D[2, 7] = 0.52780815920542364900561016686e+3
D[2, 8] = -0.11573902539959630126141871134e+2
D[2, 9] = 0.68812326946963000169666922661e+1
D[2, 10] = -0.10006050966910838403183860980e+1
D[2, 11] = 0.77771377980534432092869265740
D[2, 12] = -0.27782057523535084065932004339e+1
D[2, 13] = -0.60196695231264120758267380846e+2
D[2, 14] = 0.84320405506677161018159903784e+2
D[2, 15] = 0.11992291136182789328035130030e+2

D[3, 0] = -0.25693933462703749003312586129e+2
D[3, 5] = -0.15418974869023643374053993627e+3
D[3, 6] = -0.23152937917604549567536039109e+3
D[3, 7] = 0.35763911791061412378285349910e+3
D[3, 8] = 0.93405324183624310003907691704e+2
D[3, 9] = -0.37458323136451633156875139351e+2
D[3, 10] = 0.10409964950896230045147246184e+3
D[3, 11] = 0.29840293426660503123344363579e+2
D[3, 12] = -0.43533456590011143754432175058e+2
D[3, 13] = 0.96324553959188282948394950600e+2
D[3, 14] = -0.39177261675615439165231486172e+2
D[3, 15] = -0.14972683625798562581422125276e+3

C = np.ascontiguousarray(C)
A = np.ascontiguousarray(A)
B = np.ascontiguousarray(B)
D = np.ascontiguousarray(D)

# The error estimate behaves like that of an 8th-order method: step sizes scale with err^(-1/8).
ERROR_ORDER = 7

# Stiffness detection as in Hairer's dop853.f [HNW93, IV.2]: h*rho beyond DOP853's real stability
# boundary (about 6.1) means the step size is limited by stability.
STIFF_THRESHOLD = 6.1
# y_new minus the 12th stage's argument (both at t + h) is h * sum_j STIFF_DY[j] K[j]: formed from
# the stages (stepping.stiffness_ratio), because the two states agree to a few digits.
STIFF_DY = np.ascontiguousarray(B - A[N_STAGES - 1, :N_STAGES])

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


@njit(**_JIT_INLINE)
def dop853_step(fun, t, y, h, args, K, y_new, ys):
    """One DOP853 step of size `h` from ``(t, y)``; ``K[0]`` must hold ``f(t, y)``.

    Fills ``K[1..12]`` (``K[12] = f(t + h, y_new)``) and `y_new`; `ys` is scratch. Accepting or
    rejecting the step is the driver's business.
    """
    n = y.shape[0]
    for s in range(1, N_STAGES):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * K[j, i]
            ys[i] = y[i] + h * acc
        fun(t + C[s] * h, ys, args, K[s])
    for i in range(n):
        acc = 0.0
        for j in range(N_STAGES):
            acc += B[j] * K[j, i]
        y_new[i] = y[i] + h * acc
    fun(t + h, y_new, args, K[N_STAGES])


@njit(**_JIT)
def error_norm(K, h, y, y_new, atol, rtol):
    """Hairer's DOP853 error norm of a trial step from its stages ``K[0..12]``: at most 1 accepts."""
    n = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        yi = abs(y[i])
        yn = abs(y_new[i])
        sc = atol[i] + rtol * (yi if yi > yn else yn)
        a5 = 0.0
        a3 = 0.0
        for j in range(N_STAGES + 1):
            a5 += E5[j] * K[j, i]
            a3 += E3[j] * K[j, i]
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@njit(**_JIT_INLINE)
def dense_coefficients(fun, t, y, y_new, h, args, K, ys, q):
    """The step's ``CONTD8`` rows into ``q`` (shape ``(N_DENSE, n)``); evaluates ``K[13..15]``."""
    n = y.shape[0]
    for s in range(N_STAGES + 1, N_STAGES_EXTENDED):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * K[j, i]
            ys[i] = y[i] + h * acc
        fun(t + C[s] * h, ys, args, K[s])
    for i in range(n):
        hermite_rows(y[i], y_new[i], h, K[0, i], K[N_STAGES, i], q, i)
        for r in range(4):
            acc = 0.0
            for j in range(N_STAGES_EXTENDED):
                acc += D[r, j] * K[j, i]
            q[4 + r, i] = h * acc


@njit(**_JIT)
def _control(err, h_abs, h_max, memory, reject):
    # scipy's controller for DOP853: factor safety * err^(-1/8), in [0.2, 10], no growth
    # right after a rejection. It keeps no memory: `memory` passes through (explicit_rk's form).
    if not math.isfinite(err):
        return False, h_abs * NONFINITE_SHRINK, memory
    if err < 1.0:
        fac = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / (ERROR_ORDER + 1)))
        if reject:
            fac = min(1.0, fac)
        return True, min(h_abs * fac, h_max), memory
    return False, h_abs * max(MIN_FACTOR, SAFETY * err ** (-1.0 / (ERROR_ORDER + 1))), memory


@njit(**_JIT_INLINE)
def _trial(fun, t, y, h, args, K, y_new, ys, atol, rtol):
    # explicit_rk's trial step: the stages, y_new, and the error norm from the stages.
    dop853_step(fun, t, y, h, args, K, y_new, ys)
    return error_norm(K, h, y, y_new, atol, rtol)


@njit(**_JIT_INLINE)
def dop853(fun, event, t0, y0, t_end, args, rtol, atol, h0, h_max, T, Q, stats, rho0=0.0):
    """Integrate ``y' = fun(t, y)`` from `t0` to `t_end` with adaptive DOP853.

    Arguments, returns and counters as :func:`.rk45.dopri5` (``h0 <= 0``: Hairer's ``HINIT``
    for order 8; stiffness detection by :func:`.stepping.count_stiffness`; ``rho0`` and the
    stability check as there). Evaluations: ``1 + [h0 <= 0] + 15 * accepted + 12 * rejected``.

    The check matters most here: Hairer's blended error estimate vanishes where its 5th-order
    part does, at ``h lambda ~ -23`` for ``y' = lambda y`` (``R(h lambda) ~ -3e3``), and on
    problems whose trial stages leave the domain of a clipped right-hand side from ~2.5 times the
    stability boundary on.
    """
    return explicit_rk(_trial, _control, dense_coefficients, N_STAGES_EXTENDED, N_STAGES,
                       ERROR_ORDER, 0.0, STIFF_DY, STIFF_THRESHOLD, fun, event, t0, y0, t_end, args,
                       rtol, atol, h0, h_max, T, Q, stats, rho0)
