"""numba kernels of :mod:`workbench.conformal.intrinsic`: Delaunay test, Ptolemy flip, flip queue.

Kept apart so that a solve without flips never imports numba.
"""

from __future__ import annotations

import numba
import numpy as np

from workbench.conformal.intrinsic import DELAUNAY_TOL

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


@numba.njit(inline="always", **_JIT)
def _cos2(F, lam, u, f, k):
    i, j = F[f, (k + 1) % 3], F[f, (k + 2) % 3]
    a = lam[f, k] + u[i] + u[j]
    b = lam[f, (k + 1) % 3] + u[F[f, (k + 2) % 3]] + u[F[f, k]]
    c = lam[f, (k + 2) % 3] + u[F[f, k]] + u[F[f, (k + 1) % 3]]
    return np.exp(0.5 * (b - c)) + np.exp(0.5 * (c - b)) - np.exp(a - 0.5 * (b + c))


@numba.njit(inline="always", **_JIT)
def _arc(lam, f, k):
    # horocyclic arc of corner (f, k): l_opposite / (l_adjacent1 l_adjacent2), Penner's h-length
    return np.exp(0.5 * (lam[f, k] - lam[f, (k + 1) % 3] - lam[f, (k + 2) % 3]))


@numba.njit(inline="always", **_JIT)
def _renumber(t, f, g, k1, k2, m1, m2):
    # where an outer edge of the quad goes: ab -> f' corner 2, ca -> g' 0, bd -> f' 0, dc -> g' 2
    if t == 3 * f + k2:
        return 3 * f + 2
    if t == 3 * f + k1:
        return 3 * g
    if t == 3 * g + m1:
        return 3 * f
    if t == 3 * g + m2:
        return 3 * g + 2
    return t


@numba.njit(**_JIT)
def _flip(F, T, lam, ref_face, ref_corner, ref_off, f, k):
    t = T[f, k]
    g, m = t // 3, t % 3
    k1, k2, m1, m2 = (k + 1) % 3, (k + 2) % 3, (m + 1) % 3, (m + 2) % 3
    # f = (a, b, c) with a at corner k; g = (d, c, b) with d at corner m
    a, b, c, d = F[f, k], F[f, k1], F[f, k2], F[g, m]
    l_bc, l_ab, l_ca, l_bd, l_dc = lam[f, k], lam[f, k2], lam[f, k1], lam[g, m1], lam[g, m2]
    # Ptolemy: l_ad l_bc = l_ab l_cd + l_ac l_bd, in logarithms (no overflow at any scale)
    l_ad = 2.0 * np.logaddexp(0.5 * (l_ab + l_dc), 0.5 * (l_ca + l_bd)) - l_bc
    h_bg, h_cf = _arc(lam, g, m2), _arc(lam, f, k2)
    # new arcs: a in f' = (a, b, d) and d in g' = (d, c, a)
    h_af = np.exp(0.5 * (l_bd - l_ab - l_ad))
    h_dg = np.exp(0.5 * (l_ca - l_dc - l_ad))
    # reference directions: old corners split (a, d) or join (b, c) along the horocycles.
    # Matched by corner, not by vertex: after loops and double edges a vertex can hold
    # two corners of the quad (a == d, or b == c).
    upd_v = np.full(4, -1, dtype=np.int64)
    upd_f = np.zeros(4, dtype=np.int64)
    upd_c = np.zeros(4, dtype=np.int64)
    upd_o = np.zeros(4)
    for slot in range(4):
        v = (a, d, b, c)[slot]
        rf, rc, o = ref_face[v], ref_corner[v], ref_off[v]
        if slot == 0 and rf == f and rc == k:
            upd_v[0] = v
            upd_f[0], upd_c[0], upd_o[0] = (f, 0, o) if o < h_af else (g, 2, o - h_af)
        elif slot == 1 and rf == g and rc == m:
            upd_v[1] = v
            upd_f[1], upd_c[1], upd_o[1] = (g, 0, o) if o < h_dg else (f, 2, o - h_dg)
        elif slot == 2 and ((rf == g and rc == m2) or (rf == f and rc == k1)):
            upd_v[2] = v
            upd_f[2], upd_c[2], upd_o[2] = (f, 1, o) if rf == g else (f, 1, o + h_bg)
        elif slot == 3 and ((rf == f and rc == k2) or (rf == g and rc == m1)):
            upd_v[3] = v
            upd_f[3], upd_c[3], upd_o[3] = (g, 1, o) if rf == f else (g, 1, o + h_cf)
    for slot in range(4):
        if upd_v[slot] >= 0:
            v = upd_v[slot]
            ref_face[v], ref_corner[v], ref_off[v] = upd_f[slot], upd_c[slot], upd_o[slot]
    # outer edges; one may be glued to another outer edge of the same quad (after
    # loops and double edges), so its twin slot is renumbered like the faces
    t_ab = _renumber(T[f, k2], f, g, k1, k2, m1, m2)
    t_ca = _renumber(T[f, k1], f, g, k1, k2, m1, m2)
    t_bd = _renumber(T[g, m1], f, g, k1, k2, m1, m2)
    t_dc = _renumber(T[g, m2], f, g, k1, k2, m1, m2)
    F[f, 0], F[f, 1], F[f, 2] = a, b, d
    F[g, 0], F[g, 1], F[g, 2] = d, c, a
    lam[f, 0], lam[f, 1], lam[f, 2] = l_bd, l_ad, l_ab
    lam[g, 0], lam[g, 1], lam[g, 2] = l_ca, l_ad, l_dc
    T[f, 0], T[f, 1], T[f, 2] = t_bd, 3 * g + 1, t_ab
    T[g, 0], T[g, 1], T[g, 2] = t_ca, 3 * f + 1, t_dc
    for slot, twin in ((3 * f, t_bd), (3 * f + 2, t_ab), (3 * g, t_ca), (3 * g + 2, t_dc)):
        if twin >= 0:
            T[twin // 3, twin % 3] = slot


@numba.njit(**_JIT)
def make_delaunay(F, T, lam, u, ref_face, ref_corner, ref_off, seed_f, seed_k, max_flips):
    n = len(seed_f)
    cap = max(16, 2 * n)
    qf = np.empty(cap, dtype=np.int64)
    qk = np.empty(cap, dtype=np.int64)
    qf[:n] = seed_f
    qk[:n] = seed_k
    head, tail, flips = 0, n, 0
    while head != tail:
        f, k = qf[head % cap], qk[head % cap]
        head += 1
        t = T[f, k]
        if t < 0:
            continue
        g, m = t // 3, t % 3
        if g == f:
            continue  # an edge glued to its own triangle (a folded cone): no quad to flip
        if _cos2(F, lam, u, f, k) + _cos2(F, lam, u, g, m) >= -DELAUNAY_TOL:
            continue
        if flips == max_flips:
            return flips, False
        _flip(F, T, lam, ref_face, ref_corner, ref_off, f, k)
        flips += 1
        if tail - head + 4 > cap:
            # grow the ring buffer, unrolled from head
            bigger = 2 * cap
            nf = np.empty(bigger, dtype=np.int64)
            nk = np.empty(bigger, dtype=np.int64)
            for i in range(tail - head):
                nf[i], nk[i] = qf[(head + i) % cap], qk[(head + i) % cap]
            qf, qk, tail, head, cap = nf, nk, tail - head, 0, bigger
        # the four outer edges of the quad may have stopped being Delaunay
        for ff, kk in ((f, 0), (f, 2), (g, 0), (g, 2)):
            qf[tail % cap], qk[tail % cap] = ff, kk
            tail += 1
    return flips, True
