"""numba kernels of the pyrosequencing cascade: right-hand side and analytic Jacobian.

Arrays and scalars in, arrays out; no validation (:mod:`chiptwin.kinetics.cascade` builds the
arguments once per site). ``tests/kinetics/test_cascade.py`` checks the Jacobian against finite
differences and the right-hand side against a plain-numpy transcription of the equations.

State ``y`` of one site, all in M (L = template length)::

    y[0 .. L]         D_j    strands extended by j bases, not held back this flow
    y[L+1 .. L+4]     N_n    free dNTP, n = A (dATPαS), C, G, T
    y[L+5]            PPi
    y[L+6]            ATP
    y[L+7]            SO4    sulfate made = APS consumed          (APS = APS0 − SO4)
    y[L+8]            OXY    oxyluciferin made (light path)       (luciferin = LH0 − OXY − LAMP)
    y[L+9]            LAMP   dehydroluciferyl-AMP made (dark path)
    y[L+10]           ATPD   ATP hydrolysed by apyrase
    y[L+11 .. L+14]   NDEG_n dNTP hydrolysed by apyrase
    y[L+15]           Q      light-path turnovers since the segment started

Constants ``c`` (see :func:`chiptwin.kinetics.cascade.kernel_constants`)::

    c[0] k_pol·θ   c[1] K_d(dNTP)   c[2] V_A(ATP)   c[3] K_A(ATP)   c[4] V_A(dNTP)  c[5] K_A(dNTP)
    c[6] V_S       c[7] K_S(PPi)    c[8] K_S(APS)   c[9] APS0       c[10] V_L       c[11] K_L(ATP)
    c[12] K_L(LH)  c[13] LH0        c[14] f_LAMP    c[15] 1/K_i(oxy) c[16] 1/K_i(LAMP)

``V_X = k_cat,X [X]``. Saturation factors are ``h(c, K) = c / (K + |c|)``: the Michaelis–Menten
``c / (K + c)`` for ``c >= 0``, odd and C¹ through 0. The exact solution never leaves the
non-negative orthant (every consumption rate vanishes with its substrate); a value the solver
pushes slightly below 0 is driven back towards 0 (a negative substrate gives a negative, restoring
rate) instead of being frozen there, as clipping inside the right-hand side would do.
"""

from __future__ import annotations

import numpy as np

from chiptwin._numba import NJIT

N_SPECIES_AFTER_STRANDS = 15
"""State entries after the L + 1 strand entries."""


@NJIT
def _h(x, k):  # pragma: no cover - compiled
    """Saturation ``x / (k + |x|)`` and its derivative ``k / (k + |x|)²``."""
    d = k + abs(x)
    return x / d, k / (d * d)


@NJIT
def _rates(y, tmpl, c):  # pragma: no cover - compiled
    """Reaction velocities (M/s): polymerase per position, apyrase, sulfurylase, luciferase."""
    n_pos = tmpl.size
    i_n = n_pos + 1
    pol = np.zeros(n_pos)
    for j in range(n_pos):
        pol[j] = c[0] * y[j] * _h(y[i_n + tmpl[j]], c[1])[0]
    atp, ppi = y[i_n + 5], y[i_n + 4]
    den = 1.0 + abs(atp) / c[3]
    for n in range(4):
        den += abs(y[i_n + n]) / c[5]
    v_aatp = c[2] * atp / c[3] / den
    v_an = np.zeros(4)
    for n in range(4):
        v_an[n] = c[4] * y[i_n + n] / c[5] / den
    v_s = c[6] * _h(ppi, c[7])[0] * _h(c[9] - y[i_n + 6], c[8])[0]
    oxy, lamp = y[i_n + 7], y[i_n + 8]
    lh = c[13] - oxy - lamp
    inh = 1.0 + abs(oxy) * c[15] + abs(lamp) * c[16]
    v_l = c[10] * _h(atp, c[11])[0] * _h(lh, c[12] * inh)[0]
    return pol, v_aatp, v_an, v_s, v_l


@NJIT
def rhs(y, tmpl, c):  # pragma: no cover - compiled
    """dy/dt of one site (M/s), shape of ``y``."""
    n_pos = tmpl.size
    i_n = n_pos + 1
    pol, v_aatp, v_an, v_s, v_l = _rates(y, tmpl, c)
    dy = np.zeros(y.size)
    total_pol = 0.0
    for j in range(n_pos):
        dy[j] -= pol[j]
        dy[j + 1] += pol[j]
        dy[i_n + tmpl[j]] -= pol[j]
        total_pol += pol[j]
    for n in range(4):
        dy[i_n + n] -= v_an[n]
        dy[i_n + 10 + n] = v_an[n]
    f = c[14]
    dy[i_n + 4] = total_pol - v_s + v_l
    dy[i_n + 5] = v_s - v_l - v_aatp
    dy[i_n + 6] = v_s
    dy[i_n + 7] = (1.0 - f) * v_l
    dy[i_n + 8] = f * v_l
    dy[i_n + 9] = v_aatp
    dy[i_n + 14] = (1.0 - f) * v_l
    return dy


@NJIT
def _sign(x):  # pragma: no cover - compiled
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@NJIT
def _jac_polymerase(y, tmpl, c, jac):  # pragma: no cover - compiled
    n_pos = tmpl.size
    i_n = n_pos + 1
    for j in range(n_pos):
        col_n = i_n + tmpl[j]
        g, dg = _h(y[col_n], c[1])
        d_dd = c[0] * g  # ∂pol_j/∂D_j
        d_dn = c[0] * y[j] * dg  # ∂pol_j/∂N
        for row, sign in ((j, -1.0), (j + 1, 1.0), (col_n, -1.0), (i_n + 4, 1.0)):
            jac[row, j] += sign * d_dd
            jac[row, col_n] += sign * d_dn


@NJIT
def _jac_apyrase(y, tmpl, c, jac):  # pragma: no cover - compiled
    """Competitive apyrase on ATP and the four dNTPs: v_S = V_S (S/K_S) / (1 + Σ |S'|/K_S')."""
    i_n = tmpl.size + 1
    subs = np.empty(5, dtype=np.int64)
    vmax = np.empty(5)
    km = np.empty(5)
    for n in range(4):
        subs[n], vmax[n], km[n] = i_n + n, c[4], c[5]
    subs[4], vmax[4], km[4] = i_n + 5, c[2], c[3]
    den = 1.0
    for s in range(5):
        den += abs(y[subs[s]]) / km[s]
    for s in range(5):
        v_s = vmax[s] * y[subs[s]] / km[s] / den
        row_out = subs[s]
        row_deg = i_n + 10 + s if s < 4 else i_n + 9
        for q in range(5):
            d = -v_s / den / km[q] * _sign(y[subs[q]])
            if q == s:
                d += vmax[s] / km[s] / den
            jac[row_out, subs[q]] -= d
            jac[row_deg, subs[q]] += d


@NJIT
def _jac_sulfurylase(y, tmpl, c, jac):  # pragma: no cover - compiled
    i_n = tmpl.size + 1
    h_p, dh_p = _h(y[i_n + 4], c[7])
    h_a, dh_a = _h(c[9] - y[i_n + 6], c[8])
    d_ppi = c[6] * dh_p * h_a
    d_so4 = -c[6] * h_p * dh_a  # APS = APS0 − SO4
    for row, sign in ((i_n + 4, -1.0), (i_n + 5, 1.0), (i_n + 6, 1.0)):
        jac[row, i_n + 4] += sign * d_ppi
        jac[row, i_n + 6] += sign * d_so4


@NJIT
def _jac_luciferase(y, tmpl, c, jac):  # pragma: no cover - compiled
    """v_L = V h(ATP, K_A) m, m = LH / (K_LH inh + |LH|), LH = LH0 − OXY − LAMP."""
    i_n = tmpl.size + 1
    h_atp, dh_atp = _h(y[i_n + 5], c[11])
    oxy, lamp = y[i_n + 7], y[i_n + 8]
    lh = c[13] - oxy - lamp
    inh = 1.0 + abs(oxy) * c[15] + abs(lamp) * c[16]
    kl = c[12] * inh
    d = kl + abs(lh)
    m = lh / d
    dm_dlh = kl / (d * d)
    dm_dinh = -lh * c[12] / (d * d)
    d_atp = c[10] * dh_atp * m
    d_oxy = c[10] * h_atp * (-dm_dlh + dm_dinh * c[15] * _sign(oxy))
    d_lamp = c[10] * h_atp * (-dm_dlh + dm_dinh * c[16] * _sign(lamp))
    f = c[14]
    rows = (i_n + 4, i_n + 5, i_n + 7, i_n + 8, i_n + 14)
    signs = (1.0, -1.0, 1.0 - f, f, 1.0 - f)
    for r in range(5):
        jac[rows[r], i_n + 5] += signs[r] * d_atp
        jac[rows[r], i_n + 7] += signs[r] * d_oxy
        jac[rows[r], i_n + 8] += signs[r] * d_lamp


@NJIT
def jacobian(y, tmpl, c):  # pragma: no cover - compiled
    """∂(dy/dt)/∂y of one site, dense ``(n, n)``, unit 1/s."""
    jac = np.zeros((y.size, y.size))
    _jac_polymerase(y, tmpl, c, jac)
    _jac_apyrase(y, tmpl, c, jac)
    _jac_sulfurylase(y, tmpl, c, jac)
    _jac_luciferase(y, tmpl, c, jac)
    return jac
