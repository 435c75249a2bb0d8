"""Compiled parts of a beam level (:mod:`zwcore.arcs._search`): the candidate pieces
from a state (:func:`candidates`) and the ranked candidates verified in order until the
beam is full (:func:`select_verified`).

In Python each of the up to ``12 * beam`` checks of a level paid the call overhead of
the verification and its bookkeeping; here one call walks the ranking.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from zwcore.arcs._kernels import arc_xy, local1, verify_piece

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["candidates", "candidates_level", "select_verified"]


@njit(cache=True, nogil=True, error_model="numpy")
def select_verified(samples: FloatArray, order: IntArray, si: IntArray, j: IntArray,
                    kappa: FloatArray, sig_end: FloatArray, special: NDArray[np.bool_],
                    reach: IntArray, t_end: FloatArray, sp: FloatArray, stt: FloatArray,
                    sk: IntArray, se: FloatArray, beam: int, n_special_max: int,
                    tol: float, step0: float) -> tuple[IntArray, FloatArray]:
    """The candidates that make the next level, in the order ``order``.

    Candidate ``c`` starts from state ``si[c]`` (point ``sp``, tangent ``stt``, sample
    ``sk``, distance ``se``, arrays over the states) and covers samples up to ``j[c]``
    with curvature ``kappa[c]`` (length ``sig_end[c]``, NaN: to the foot point of
    ``j[c]``). At most ``beam`` pass (at most ``n_special_max`` of them ``special``),
    at most ``12 * beam`` are verified, and one per end state: its reach, end sample and
    end direction (milliradians). Returns the indices of those that passed and their
    ``(length, end x, end y, e_end)`` ``(n, 4)``.
    """
    out = np.empty(beam, dtype=np.int64)
    figs = np.empty((beam, 4))
    keys = np.empty((beam, 3))
    n = 0
    checks = 0
    n_special = 0
    for i in order:
        if n >= beam or checks >= 12 * beam:
            break
        if special[i] and n_special >= n_special_max:
            continue
        key_a = float(reach[i])
        key_b = float(j[i])
        key_c = np.rint(math.atan2(t_end[i, 1], t_end[i, 0]) * 1e3)
        dup = False
        for m in range(n):
            if keys[m, 0] == key_a and keys[m, 1] == key_b and keys[m, 2] == key_c:
                dup = True
                break
        if dup:
            continue
        checks += 1
        s = si[i]
        given = not math.isnan(sig_end[i])
        ok, length, ex, ey, e_end = verify_piece(
            samples, sp[s, 0], sp[s, 1], stt[s, 0], stt[s, 1], kappa[i], sk[s], j[i], se[s],
            sig_end[i] if given else 0.0, given, False, tol, step0)
        if not ok:
            continue
        keys[n, 0], keys[n, 1], keys[n, 2] = key_a, key_b, key_c
        out[n] = i
        figs[n, 0], figs[n, 1], figs[n, 2], figs[n, 3] = length, ex, ey, e_end
        n += 1
        if special[i]:
            n_special += 1
    return out[:n], figs[:n]


@njit(cache=True, nogil=True, error_model="numpy")
def candidates(samples: FloatArray, cum: FloatArray, px: float, py: float, tx: float,
               ty: float, k: int, jm: int, lo1: FloatArray, up1: FloatArray,
               j_fractions: FloatArray, k_fractions: FloatArray,
               kcap: float) -> tuple[IntArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Candidate pieces from the junction ``(p, t)`` at sample ``k`` (no radius floor).

    Ends: the samples at the shares ``j_fractions`` of the longest feasible piece's length
    (up to sample ``jm``), longest first; per end a line when the running bounds
    ``lo1, up1`` allow one, then the shares ``k_fractions`` of its curvature interval
    (capped at ``kcap``). Each piece ends at the foot point of its end sample. Returns
    ``(j, kappa, end (C, 2), end tangent (C, 2), bonus)``, the bonus favouring lines by
    0.3 of their length (see :meth:`zwcore.arcs._search.Fitter._candidates`).
    """
    span = cum[jm] - cum[k]
    nj = len(j_fractions)
    js = np.empty(nj, dtype=np.int64)
    for i in range(nj):
        at = np.searchsorted(cum, cum[k] + j_fractions[i] * span, side="right")
        js[i] = min(max(at - 1, k + 1), jm)
    js = np.unique(js)[::-1]
    nk = len(k_fractions) + 1
    cap = len(js) * nk
    jj = np.empty(cap, dtype=np.int64)
    kk = np.empty(cap)
    n = 0
    for j in js:
        lo = max(lo1[j - k - 1], -kcap)
        hi = min(up1[j - k - 1], kcap)
        if not lo <= hi:
            continue
        if lo <= 0.0 <= hi:
            jj[n] = j
            kk[n] = 0.0
            n += 1
        for f in k_fractions:
            jj[n] = j
            kk[n] = lo + f * (hi - lo)
            n += 1
    ends = np.empty((n, 2))
    tends = np.empty((n, 2))
    bonus = np.zeros(n)
    for i in range(n):
        j = jj[i]
        kap = kk[i]
        u, v = local1(samples[j, 0], samples[j, 1], px, py, tx, ty)
        if kap == 0.0:
            sj = u
            bonus[i] = 0.3 * (cum[j] - cum[k])
        else:
            sj = math.atan2(kap * u, 1.0 - kap * v) / kap
        ends[i, 0], ends[i, 1] = arc_xy(px, py, tx, ty, kap, sj)
        c, s = math.cos(kap * sj), math.sin(kap * sj)
        tends[i, 0] = c * tx - s * ty
        tends[i, 1] = s * tx + c * ty
    return jj[:n], kk[:n], ends, tends, bonus


@njit(cache=True, nogil=True, error_model="numpy")
def candidates_level(samples: FloatArray, cum: FloatArray, sp: FloatArray, stt: FloatArray,
                     sk: IntArray, sjm: IntArray, lo_all: FloatArray, up_all: FloatArray,
                     b_off: IntArray, j_fractions: FloatArray, k_fractions: FloatArray,
                     kcap: float) -> tuple[IntArray, IntArray, FloatArray, FloatArray,
                                           FloatArray, FloatArray]:
    """:func:`candidates` from every state of a level at once, in the states' order.

    State ``s`` is the junction ``(sp[s], stt[s])`` at sample ``sk[s]`` whose longest
    piece reaches sample ``sjm[s]`` (none: ``sjm[s] <= sk[s]``), with running curvature
    bounds ``lo_all, up_all[b_off[s]:b_off[s + 1]]``. Returns ``(si, j, kappa, end (C, 2),
    end tangent (C, 2), bonus)``, ``si`` the state of each candidate.
    """
    ns = len(sk)
    cap = 0
    for s in range(ns):
        if sjm[s] > sk[s]:
            cap += len(j_fractions) * (len(k_fractions) + 1)
    si = np.empty(cap, dtype=np.int64)
    jj = np.empty(cap, dtype=np.int64)
    kk = np.empty(cap)
    ends = np.empty((cap, 2))
    tends = np.empty((cap, 2))
    bonus = np.empty(cap)
    n = 0
    for s in range(ns):
        if sjm[s] <= sk[s]:
            continue
        j1, k1, e1, t1, b1 = candidates(
            samples, cum, sp[s, 0], sp[s, 1], stt[s, 0], stt[s, 1], sk[s], sjm[s],
            lo_all[b_off[s] : b_off[s + 1]], up_all[b_off[s] : b_off[s + 1]], j_fractions,
            k_fractions, kcap)
        m = len(j1)
        si[n : n + m] = s
        jj[n : n + m] = j1
        kk[n : n + m] = k1
        ends[n : n + m] = e1
        tends[n : n + m] = t1
        bonus[n : n + m] = b1
        n += m
    return si[:n], jj[:n], kk[:n], ends[:n], tends[:n], bonus[:n]
