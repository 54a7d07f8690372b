"""The slot layouts the solver's kernels report through: per ``(eta, A, N)`` result vector
(``R_*``), profile rows (``P_*``), stage 1's path and method codes.

Plain constants, no numba: :mod:`cosserat_channel.outputs`, the sweep and the point API read them
to turn the kernels' float vectors into named results.
"""

# Slots of the per-(eta, A, N) result vector of `solve_eta`.
R_STATUS = 0
R_XI_STOP = 1  # where the stress path met D = 0 (eps_too_large_path), NaN otherwise
R_J_AXIS = 2  # J(0) = u(0)/omega_w - eps K
R_MU_WALL = 3  # m(1)/(nu L)
R_SIGMA_YX_WALL = 4  # sigma_yx(1)/nu
R_XI1 = 5  # where stage 1 left the axis series
R_T_TAIL = 6  # ln(xi) where stage 2 stopped
R_N1 = 7  # accepted steps kept in the stage-1 dense output
R_N2 = 8
R_PATH = 9  # stage 1 took the explicit (0) or the stiff (1) path; -1: not integrated
# Below XI2 stage 2 is the closed form of model.stage2_series (NaN: marched down to R_T_TAIL)
R_XI2 = 10
R_LOGW2 = 11  # log(omega_hat) at XI2
R_J2 = 12  # J at XI2
R_LOGI2 = 13  # log int_0^XI2 h omega_hat (the plug-edge root below XI2 starts from it)
R_RTOL1 = 14  # the relative tolerance stage 1 finally ran at
N_R = 15
PATH_EXPLICIT = 0.0
PATH_STIFF = 1.0
PATH_NONE = -1.0  # no stage-1 integration: a regime without solution, or A = -1 (exact)
PATH_NAMES = {PATH_EXPLICIT: "explicit", PATH_STIFF: "stiff", PATH_NONE: "none"}

METHOD_AUTO = 0
METHOD_EXPLICIT = 1
METHOD_STIFF = 2

# Rows of a triple's profile array (see profile_kernel).
P_J = 0  # J(xi) = u(xi)/omega_w - eps K
P_OMEGA_HAT = 1  # omega(xi)/omega_w
P_DELTA = 2  # (m/nu + N L)/L
P_SIGMA_YX = 3  # sigma_yx/nu
N_PROF = 4
