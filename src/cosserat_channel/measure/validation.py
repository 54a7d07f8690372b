"""The validation set of the work-precision report and its reference values, cached on disk.

The set is drawn from a fixed seed in three strata:

- ``bulk``: ``eps`` log-uniform in [1e-6, 0.5], ``L`` log-uniform in [0.5, 100], ``K`` log-uniform
  in [1e-2, 1e3], ``A`` uniform in (-1, 5], ``N`` log-uniform in [0.3, 10];
- ``stiff``: the same, but ``eta = eps L`` log-uniform in [1e-6, 1e-3] (the stiff path);
- ``edge``: ``(A, N)`` as in bulk, ``eta`` a relative gap of 10^U(-3, -1) below the largest
  ``eta`` at which stage 1 still reaches the wall (found by bisection with our stage 1 at rtol
  1e-11, rounded to 6 digits; the gap is far above that location's error, so the choice of
  points does not depend on our solver's accuracy, and the reference alone decides whether a
  point is kept).

``K = 0`` is left out on purpose: it gives ``slip = 0``, which has no relative error (K costs no
integration, so nothing is lost). Candidates are screened with the exact algebraic regime tests
(:func:`reference.classify`) and then kept only if

1. the reference (``reference.reference``, Radau at rtol 1e-12) has status ``ok``;
2. ``slip <= 0.9`` and ``|m_wall| >= 1e-3 N L``: away from ``Delta = 0`` (where the relative error
   of ``Delta`` is amplified by ``0.95 J(0) / (0.95 J(0) - 0.05 eps K)``, unbounded at slip 0.95)
   and from sign changes of ``m_wall``;
3. where ``eta >= 1e-3``, DOP853 at rtol 1e-12 agrees with Radau to 1e-9 (relative, on Delta,
   m_wall and slip). Below ``eta = 1e-3`` DOP853 needs O(1/eta) steps (minutes per point in
   Python), so those points rest on Radau alone.

Where both exist the DOP853 value is the reference (its dense output, which feeds stage 2, is
of order 7 against Radau's 3). The points and values are cached in ``reference_cache.npz`` under
a key hashing the set definition, :data:`GENERATOR_VERSION` and the source of
:mod:`cosserat_channel.physics.reference`; a rerun with the same key reuses them. While the set
is built, each candidate's reference is kept in ``reference_cache.partial.npz`` as soon as it is
computed, so a build that is interrupted (Ctrl-C, a kill) resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import math
import os
from dataclasses import asdict, dataclass, field

import numpy as np

from ..physics import reference as ref_mod
from .. import regimes
from ..files import write_npz

SEED = 20261121
# Bump when the sampling below changes, the edge bisection (regimes.bisect_edge) included: the
# cache key includes it, not the code.
GENERATOR_VERSION = 1
REF_RTOL = 1e-12
CROSS_CHECK_TOL = 1e-9
DOP853_MIN_ETA = 1e-3
MAX_SLIP = 0.9
MIN_ABS_M_OVER_NL = 1e-3
EDGE_XTOL = 1e-12  # relative width of the bisected edge of the edge stratum, before rounding
QUANTITIES = ("Delta", "m_wall", "slip")
STRATA = ("bulk", "stiff", "edge")


@dataclass(frozen=True)
class SetSpec:
    """Everything that defines the validation set (and keys its cache)."""

    size: int = 300
    seed: int = SEED
    fractions: tuple = (0.6, 0.2, 0.2)  # bulk, stiff, edge
    eps: tuple = (1e-6, 0.5)
    L: tuple = (0.5, 100.0)
    K: tuple = (1e-2, 1e3)
    A: tuple = (-1.0, 5.0)  # (lo, hi]: lo itself excluded
    N: tuple = (0.3, 10.0)
    stiff_eta: tuple = (1e-6, 1e-3)
    edge_gap: tuple = (1e-3, 1e-1)
    max_candidates_factor: int = 20

    def quotas(self) -> dict:
        n_stiff = int(round(self.fractions[1] * self.size))
        n_edge = int(round(self.fractions[2] * self.size))
        return {"bulk": self.size - n_stiff - n_edge, "stiff": n_stiff, "edge": n_edge}

    def key(self) -> str:
        """Hash of the definition, the generator version and reference.py's source."""
        h = hashlib.sha256()
        h.update(json.dumps(asdict(self), sort_keys=True).encode())
        h.update(f"generator {GENERATOR_VERSION}; rtol {REF_RTOL}; tol {CROSS_CHECK_TOL}".encode())
        h.update(inspect.getsource(ref_mod).encode())
        return h.hexdigest()[:20]


@dataclass
class ValidationSet:
    """Points ``(eps, L, K, A, N)``, their stratum and reference values, and how they were chosen."""

    spec: SetSpec
    eps: np.ndarray
    L: np.ndarray
    K: np.ndarray
    A: np.ndarray
    N: np.ndarray
    stratum: np.ndarray  # index into STRATA
    ref: dict  # quantity -> array (DOP853 where computed, else Radau)
    cross_checked: np.ndarray  # bool: DOP853 computed and compared
    disagreement: np.ndarray  # max relative Radau/DOP853 difference over QUANTITIES (NaN if not checked)
    counts: dict = field(default_factory=dict)  # candidates tried / dropped, by reason
    reused: bool = False

    @property
    def size(self) -> int:
        return int(self.eps.size)

    @property
    def eta(self) -> np.ndarray:
        return self.eps * self.L


# ---------------------------------------------------------------------------------------------
# Sampling
# ---------------------------------------------------------------------------------------------
def _log_uniform(rng, lo, hi, n=None):
    return np.exp(rng.uniform(math.log(lo), math.log(hi), n))


def _draw_AN(rng, spec):
    """``(A, N)`` with A uniform in (lo, hi] and N log-uniform, in the model's A > -1 regime."""
    while True:
        A = spec.A[1] - (spec.A[1] - spec.A[0]) * rng.random()  # (lo, hi]
        N = _log_uniform(rng, *spec.N)
        if A > spec.A[0] and A >= 1.0 - 2.0 * N * N:
            return float(A), float(N)


def _L_for_eta(rng, eta, spec):
    """``L`` log-uniform in the part of its range where ``eps = eta / L`` stays in range."""
    lo = max(spec.L[0], eta / spec.eps[1])
    hi = min(spec.L[1], eta / spec.eps[0])
    if not lo <= hi:
        return None
    return float(_log_uniform(rng, lo, hi))


def _stage1_reaches_wall(eta, A, N):
    """Our stage 1 (rtol 1e-11) reaches the wall at each ``eta`` (used only to find the edge)."""
    from ..solver import batch, layout, stage1

    n = eta.size
    mu = np.empty(n)
    stats = batch.new_statistics(n)
    batch.stage1_batch(np.ascontiguousarray(eta), np.full(n, A), np.full(n, N), 1e-11, 1e-14,
                       layout.METHOD_AUTO, stage1.MAX_STEPS_STAGE1, mu, stats)
    return np.isfinite(mu)


def _edge_eta(A, N, spec):
    """The largest ``eta`` in the allowed range at which stage 1 reaches the wall, or None.

    Bisected (:func:`cosserat_channel.regimes.bisect_edge`) to ``EDGE_XTOL``, far below the
    6 digits it is rounded to, so that the rounded value, and with it the set, does not depend on
    where inside its last bracket the bisection stops.
    """
    lo, hi = spec.stiff_eta[1], spec.eps[1] * spec.L[1]
    ok = _stage1_reaches_wall(np.array([lo, hi]), A, N)
    if not ok[0] or ok[1]:
        return None  # no edge inside the range
    lo, _ = regimes.bisect_edge(lambda eta: bool(_stage1_reaches_wall(np.array([eta]), A, N)[0]),
                                lo, hi, EDGE_XTOL)
    return float(f"{lo:.6g}")


def _candidate(rng, stratum, spec):
    """One candidate ``(eps, L, K, A, N)`` of a stratum, or None (redraw)."""
    K = float(_log_uniform(rng, *spec.K))
    if stratum == "bulk":
        eps = float(_log_uniform(rng, *spec.eps))
        L = float(_log_uniform(rng, *spec.L))
        A, N = _draw_AN(rng, spec)
        return eps, L, K, A, N
    A, N = _draw_AN(rng, spec)
    if stratum == "stiff":
        eta = float(_log_uniform(rng, *spec.stiff_eta))
    else:
        gap = float(_log_uniform(rng, *spec.edge_gap))
        eta_c = _edge_eta(A, N, spec)
        if eta_c is None:
            return None
        eta = eta_c * (1.0 - gap)
    L = _L_for_eta(rng, eta, spec)
    if L is None:
        return None
    return eta / L, L, K, A, N


# ---------------------------------------------------------------------------------------------
# References
# ---------------------------------------------------------------------------------------------
def _rel(a, b):
    return abs(a - b) / abs(b) if b != 0 else abs(a - b)


def _reference_point(p):
    """``(values, cross_checked, disagreement, reason)``; ``reason`` is None when kept."""
    eps, L, K, A, N = p
    if ref_mod.classify(eps, L, A, N) is not None:
        return None, False, math.nan, "regime"
    r = ref_mod.reference(eps, L, K, A, N, method="Radau", rtol=REF_RTOL)
    if r["status"] != "ok":
        return None, False, math.nan, "status"
    if not (r["slip"] <= MAX_SLIP and abs(r["m_wall"]) >= MIN_ABS_M_OVER_NL * N * L):
        return None, False, math.nan, "conditioning"
    values = {q: float(r[q]) for q in QUANTITIES}
    if eps * L < DOP853_MIN_ETA:
        return values, False, math.nan, None
    d = ref_mod.reference(eps, L, K, A, N, method="DOP853", rtol=REF_RTOL)
    if d["status"] != "ok":
        return None, True, math.inf, "disagree"
    dis = max(_rel(values[q], float(d[q])) for q in QUANTITIES)
    if not dis <= CROSS_CHECK_TOL:
        return None, True, dis, "disagree"
    return {q: float(d[q]) for q in QUANTITIES}, True, dis, None


PARTIAL_NAME = "reference_cache.partial.npz"
_REASONS = ("", "regime", "status", "conditioning", "disagree")  # "": kept


class _Partial:
    """Each candidate's reference result, on disk from the moment it is computed.

    The candidates are drawn from the seed, so a rebuild meets the same points in the same
    order and takes the results it finds here instead of computing them again (the key is the
    set's, :meth:`SetSpec.key`; a file with another key is ignored and replaced).
    """

    def __init__(self, spec: SetSpec, path=None):
        self.path, self.key, self.done = path, spec.key(), {}
        if path is None:
            return
        try:
            with np.load(os.fspath(path)) as z:
                if str(z["key"]) != self.key:
                    return
                for p, r, v, c, d in zip(z["points"], z["reason"], z["values"], z["checked"],
                                         z["disagreement"]):
                    values = None if r else dict(zip(QUANTITIES, map(float, v)))
                    self.done[tuple(map(float, p))] = (values, bool(c), float(d), str(r) or None)
        except (OSError, KeyError, ValueError):
            self.done = {}

    def get(self, p):
        return self.done.get(tuple(map(float, p)))

    def put(self, p, result) -> None:
        self.done[tuple(map(float, p))] = result
        if self.path is not None:
            self._save()

    def _save(self) -> None:
        rows = list(self.done.items())
        arrays = {
            "key": np.array(self.key),
            "points": np.array([p for p, _ in rows], float).reshape(-1, 5),
            "reason": np.array([r[3] or "" for _, r in rows], dtype=f"<U{max(map(len, _REASONS))}"),
            "values": np.array([[math.nan] * len(QUANTITIES) if r[0] is None
                                else [r[0][q] for q in QUANTITIES] for _, r in rows],
                               float).reshape(-1, len(QUANTITIES)),
            "checked": np.array([r[1] for _, r in rows], bool),
            "disagreement": np.array([r[2] for _, r in rows], float),
        }

        write_npz(self.path, arrays)


def partial_count(spec: SetSpec, directory) -> int:
    """How many candidates of ``spec``'s set have their reference kept in ``directory``."""
    return len(_Partial(spec, os.path.join(os.fspath(directory), PARTIAL_NAME)).done)


def build(spec: SetSpec, log=None, partial=None) -> ValidationSet:
    """Draw the set and compute its references (slow: ~1 s per point in Python).

    ``partial``: a path where each candidate's reference is kept as soon as it is computed, and
    read back from, so that an interrupted build resumes (:class:`_Partial`).
    """
    done = _Partial(spec, partial)
    if log is not None and done.done:
        log(f"reference: resuming from {partial} ({len(done.done)} candidates done before)")
    rng = np.random.default_rng(spec.seed)
    quotas = spec.quotas()
    counts = {"candidates": 0, "regime": 0, "status": 0, "conditioning": 0, "disagree": 0,
              "max_disagreement_dropped": 0.0}
    cols = {k: [] for k in ("eps", "L", "K", "A", "N", "stratum", "checked", "dis")}
    refs = {q: [] for q in QUANTITIES}
    for s_index, stratum in enumerate(STRATA):
        kept = 0
        tried = 0
        draws = 0
        limit = spec.max_candidates_factor * max(quotas[stratum], 1)
        while kept < quotas[stratum] and tried < limit and draws < 5 * limit:
            draws += 1
            p = _candidate(rng, stratum, spec)
            if p is None:  # no edge in range for this (A, N), or no L to match eta
                continue
            tried += 1
            result = done.get(p)
            if result is None:
                result = _reference_point(p)
                done.put(p, result)
            values, checked, dis, reason = result
            if reason is not None:
                counts[reason] += 1
                if reason == "disagree":
                    counts["max_disagreement_dropped"] = max(counts["max_disagreement_dropped"], dis)
                continue
            kept += 1
            for k, v in zip(("eps", "L", "K", "A", "N"), p):
                cols[k].append(v)
            cols["stratum"].append(s_index)
            cols["checked"].append(checked)
            cols["dis"].append(dis)
            for q in QUANTITIES:
                refs[q].append(values[q])
            if log is not None and kept % 25 == 0:
                log(f"reference: {stratum} {kept}/{quotas[stratum]}")
        counts["candidates"] += tried
        counts[f"kept_{stratum}"] = kept
    return ValidationSet(
        spec=spec,
        eps=np.array(cols["eps"]), L=np.array(cols["L"]), K=np.array(cols["K"]),
        A=np.array(cols["A"]), N=np.array(cols["N"]),
        stratum=np.array(cols["stratum"], dtype=np.int64),
        ref={q: np.array(refs[q]) for q in QUANTITIES},
        cross_checked=np.array(cols["checked"], dtype=bool),
        disagreement=np.array(cols["dis"], dtype=float),
        counts=counts,
    )


# ---------------------------------------------------------------------------------------------
# Cache
# ---------------------------------------------------------------------------------------------
CACHE_NAME = "reference_cache.npz"


def save(vs: ValidationSet, path) -> None:
    """Write the set to ``path`` atomically (:func:`cosserat_channel.files.atomic_output`)."""
    arrays = {k: getattr(vs, k) for k in ("eps", "L", "K", "A", "N", "stratum", "cross_checked",
                                           "disagreement")}
    arrays.update({f"ref_{q}": vs.ref[q] for q in QUANTITIES})

    write_npz(path, dict(key=np.array(vs.spec.key()), counts=np.array(json.dumps(vs.counts)),
                         spec=np.array(json.dumps(asdict(vs.spec))), **arrays))


def load(spec: SetSpec, path) -> ValidationSet | None:
    """The cached set at ``path`` if its key matches ``spec``'s, else None."""
    try:
        with np.load(os.fspath(path)) as z:
            if str(z["key"]) != spec.key():
                return None
            return ValidationSet(
                spec=spec,
                **{k: z[k] for k in ("eps", "L", "K", "A", "N", "stratum", "cross_checked",
                                     "disagreement")},
                ref={q: z[f"ref_{q}"] for q in QUANTITIES},
                counts=json.loads(str(z["counts"])),
                reused=True,
            )
    except (OSError, KeyError, ValueError):
        return None


def get(spec: SetSpec, directory, log=None) -> ValidationSet:
    """The set for ``spec``: from ``directory/reference_cache.npz`` when its key matches, else
    built (resuming from ``directory/reference_cache.partial.npz``) and cached there."""
    path = os.path.join(os.fspath(directory), CACHE_NAME)
    vs = load(spec, path)
    if vs is not None:
        if log is not None:
            log(f"reference: reusing {path} ({vs.size} points, key {spec.key()})")
        return vs
    if log is not None:
        log(f"reference: computing {spec.size} points (cached in {path} afterwards)")
    partial = os.path.join(os.fspath(directory), PARTIAL_NAME)
    vs = build(spec, log, partial)
    save(vs, path)
    try:
        os.unlink(partial)
    except FileNotFoundError:
        pass
    return vs
