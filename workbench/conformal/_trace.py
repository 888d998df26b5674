"""numba kernel of :func:`workbench.conformal.overlay.trace_input_edges` (see there for the geometry)."""

from __future__ import annotations

import numba
import numpy as np

from workbench.conformal._flips import _JIT, _arc


@numba.njit(inline="always", **_JIT)
def _sigmoid(x):
    # q / (1 + q) for q = e^x, without overflow either way
    if x >= 0:
        return 1.0 / (1.0 + np.exp(-x))
    e = np.exp(x)
    return e / (1.0 + e)


@numba.njit(**_JIT)
def _fan_offset(F, T, lam, f, k, b):
    # horocyclic offset of edge a -> b counter-clockwise from a's reference corner (f, k)
    f0, k0, acc = f, k, 0.0
    while True:
        if F[f, (k + 1) % 3] == b:
            return acc
        acc += _arc(lam, f, k)
        t = T[f, (k + 1) % 3]
        if t < 0:
            return acc if F[f, (k + 2) % 3] == b else -1.0
        f, k = t // 3, (t % 3 + 1) % 3
        if f == f0 and k == k0:
            return -1.0


@numba.njit(**_JIT)
def trace(E, lam_e, F_in, T_in, lam_in, in_ref_face, in_ref_corner, F, T, lam, ref_face, ref_corner, ref_off, u):
    """Crossings of input edges ``E`` (#E, 2) with the flipped triangulation ``F``.

    Returns ``(edge, t_in, out_id, t_out, failed)``: per crossing the row of ``E``,
    the position along it, the flat edge's smaller corner slot and the position along
    that edge as its face runs it; ``failed`` is the first edge that could not be
    traced, or -1.
    """
    cap = max(1024, 2 * len(E))
    edge = np.empty(cap, dtype=np.int64)
    t_in = np.empty(cap)
    out_id = np.empty(cap, dtype=np.int64)
    t_out = np.empty(cap)
    n = 0
    nF = len(F)
    for e in range(len(E)):
        a, b = E[e, 0], E[e, 1]
        s = _fan_offset(F_in, T_in, lam_in, in_ref_face[a], in_ref_corner[a], b)
        if s < 0:
            return edge[:n], t_in[:n], out_id[:n], t_out[:n], e
        # walk a's corners in the flipped triangulation to the one the direction leaves through
        f, k = ref_face[a], ref_corner[a]
        r = ref_off[a] + s
        for _ in range(4 * nF):
            h = _arc(lam, f, k)
            if r < h:
                break
            t = T[f, (k + 1) % 3]
            if t < 0:
                r = h * (1 - 1e-12)  # round-off past the last corner of a boundary vertex
                break
            r -= h
            f, k = t // 3, (t % 3 + 1) % 3
        h = _arc(lam, f, k)
        v, w = F[f, (k + 1) % 3], F[f, (k + 2) % 3]
        # leaving along an edge of the flipped triangulation that ends at b: that edge
        if (r <= 1e-9 * h and v == b) or (h - r <= 1e-9 * h and w == b):
            continue
        lam_av, lam_aw = lam[f, (k + 2) % 3], lam[f, (k + 1) % 3]
        x_v, x_w = 0.0, h
        x = min(max(r, 0.0), h)
        ce, ck = f, k
        done = False
        for _step in range(nF + 1):
            dv, dw = max(x - x_v, 1e-300), max(x_w - x, 1e-300)
            if n == cap:
                cap *= 2
                edge2, t_in2 = np.empty(cap, dtype=np.int64), np.empty(cap)
                out2, t_out2 = np.empty(cap, dtype=np.int64), np.empty(cap)
                edge2[:n], t_in2[:n], out2[:n], t_out2[:n] = edge[:n], t_in[:n], out_id[:n], t_out[:n]
                edge, t_in, out_id, t_out = edge2, t_in2, out2, t_out2
            edge[n] = e
            # along the input edge: β_b/β_a = 1 / (l_ab² y²) with a's horocycle at height 1
            t_in[n] = _sigmoid(-lam_e[e] - np.log(dv * dw))
            # along the flat edge: β_w/β_v = (x - x_v) l_av² / ((x_w - x) l_aw²), then b̃_i ∝ β_i e^{-u_i}
            tt = _sigmoid(np.log(dv) - np.log(dw) + lam_av - lam_aw + u[v] - u[w])
            twin = T[ce, ck]
            if twin < 3 * ce + ck:
                out_id[n], t_out[n] = twin, 1.0 - tt
            else:
                out_id[n], t_out[n] = 3 * ce + ck, tt
            n += 1
            t = T[ce, ck]
            if t < 0:
                return edge[:n], t_in[:n], out_id[:n], t_out[:n], e
            g, m = t // 3, t % 3
            d = F[g, m]
            # g = (d, w, v): l_vd opposite w (corner m+1), l_dw opposite v (corner m+2)
            lam_vw, lam_vd, lam_dw = lam[g, m], lam[g, (m + 1) % 3], lam[g, (m + 2) % 3]
            lam_ad = 2.0 * np.logaddexp(0.5 * (lam_av + lam_dw), 0.5 * (lam_aw + lam_vd)) - lam_vw
            x_d = x_v + np.exp(0.5 * (lam_vd - lam_av - lam_ad))
            if d == b and abs(x_d - x) <= 1e-6 * (x_w - x_v):
                done = True
                break
            if x < x_d:
                w, lam_aw, x_w, ce, ck = d, lam_ad, x_d, g, (m + 1) % 3
            else:
                v, lam_av, x_v, ce, ck = d, lam_ad, x_d, g, (m + 2) % 3
        if not done:
            return edge[:n], t_in[:n], out_id[:n], t_out[:n], e
    return edge[:n], t_in[:n], out_id[:n], t_out[:n], -1
