"""Compiled loops of the range-tracking EKF (Jiang 2018 §4.4), one call for a whole log.

Private. :mod:`rangekit.localize.range_ekf` flattens a measurement log into the arrays
below and calls :func:`run_range_ekf` (one hypothesis) or :func:`run_bank` (the
hypothesis bank with both mirror branches); the same module has a plain-numpy reference
built on :func:`rangekit.localize.ekf.update` and a Python-driven bank, and
``tests/localize/test_range_ekf.py`` checks they agree to rounding.

State: for each of N targets ``[x, y, vx, vy]`` (d = 4N), constant velocity driven by
white acceleration of spectral density ``q[t]`` (m²/s³ per axis) for target t.

Measurement rows (scalar), per epoch a contiguous slice ``start[e]:start[e+1]``:

====  ==========================================================================
kind  meaning
====  ==========================================================================
0     range robot -> target ``b``; its noise also carries the robot position error
1     range target ``a`` -> target ``b``
2, 3  x (2) or y (3) of target ``b`` in the world frame (robot pose + relative fix);
      rows 2 and 3 of one fix are adjacent, ``cov`` holds their noise covariance
====  ==========================================================================

Noise model (Jiang 2018 eqs (7), (9), (11)–(13), generalised): the measurement error is
``G e_r + n`` with ``e_r`` the robot position error (covariance ``P_r``) and ``n``
independent per row (variance ``var``; x/y of a fix correlated by ``cov``), so
``R = G P_r G^T + N``. ``G`` is ``sign * u^T`` for a robot range (``u`` the unit vector
robot -> target; ``sign`` +1 is the physical sign, -1 the sign printed in eq (12)), the
unit vector of the axis for a fix row, and 0 for target-target ranges.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rangekit.localize.range_ekf import ITER_TOL_M2

LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True)
def cv_predict(x, P, dt, q, xo, Po):  # pragma: no cover - compiled
    """x, P -> xo, Po over ``dt`` s for the constant-velocity model (in place into xo, Po)."""
    d = x.size
    n_t = d // 4
    for i in range(d):
        xo[i] = x[i]
    for t in range(n_t):
        o = 4 * t
        xo[o] += dt * x[o + 2]
        xo[o + 1] += dt * x[o + 3]
    # Po = F P F^T: F adds dt * velocity rows to position rows
    for i in range(d):
        for j in range(d):
            Po[i, j] = P[i, j]
    for t in range(n_t):  # rows
        o = 4 * t
        for j in range(d):
            Po[o, j] += dt * P[o + 2, j]
            Po[o + 1, j] += dt * P[o + 3, j]
    for t in range(n_t):  # columns
        o = 4 * t
        for i in range(d):
            Po[i, o] += dt * Po[i, o + 2]
            Po[i, o + 1] += dt * Po[i, o + 3]
    for t in range(n_t):
        o = 4 * t
        a = q[t] * dt * dt * dt / 3.0
        b = q[t] * dt * dt / 2.0
        c = q[t] * dt
        for k in range(2):
            Po[o + k, o + k] += a
            Po[o + k, o + 2 + k] += b
            Po[o + 2 + k, o + k] += b
            Po[o + 2 + k, o + 2 + k] += c


@njit(cache=True)
def _linearise(x, kind, a, b, val, lo, hi, rx, ry, sign, z, zh, H, G, ok):  # pragma: no cover
    """Rows lo..hi-1: measured z, predicted zh, Jacobian H, robot-error map G, usable ok."""
    d = x.size
    for r in range(hi - lo):
        i = lo + r
        k = kind[i]
        z[r] = val[i]
        for j in range(d):
            H[r, j] = 0.0
        G[r, 0] = 0.0
        G[r, 1] = 0.0
        ok[r] = True
        ob = 4 * b[i]
        if k == 0 or k == 1:
            if k == 0:
                ax, ay = rx, ry
            else:
                oa = 4 * a[i]
                ax, ay = x[oa], x[oa + 1]
            dx = x[ob] - ax
            dy = x[ob + 1] - ay
            dist = math.sqrt(dx * dx + dy * dy)
            if dist < 1e-9 or not math.isfinite(val[i]):
                ok[r] = False
                zh[r] = 0.0
                continue
            zh[r] = dist
            ux, uy = dx / dist, dy / dist
            H[r, ob] = ux
            H[r, ob + 1] = uy
            if k == 1:
                oa = 4 * a[i]
                H[r, oa] = -ux
                H[r, oa + 1] = -uy
            else:
                G[r, 0] = sign * ux
                G[r, 1] = sign * uy
        else:
            c = k - 2
            zh[r] = x[ob + c]
            H[r, ob + c] = 1.0
            G[r, c] = 1.0


@njit(cache=True)
def _chol_inplace(S, m):  # pragma: no cover - compiled
    """Lower Cholesky factor of S[:m, :m] in place; False if not positive definite."""
    for j in range(m):
        s = S[j, j]
        for k in range(j):
            s -= S[j, k] * S[j, k]
        if not (s > 0.0):
            return False
        s = math.sqrt(s)
        S[j, j] = s
        for i in range(j + 1, m):
            t = S[i, j]
            for k in range(j):
                t -= S[i, k] * S[j, k]
            S[i, j] = t / s
        for i in range(j):
            S[i, j] = 0.0
    return True


@njit(cache=True)
def epoch_update(
    x, P, xlin, n_iter, kind, a, b, val, var, cov, lo, hi, rx, ry, Pr, sign, thr,
    gate_kind_max, acc, nis_out, inno_out, mean_only=False,
):  # pragma: no cover - compiled  # fmt: skip
    """One joint (iterated) EKF update with the rows lo..hi-1, after per-row gating.

    ``x, P`` hold the prior on entry and the posterior on exit. The measurement model is
    linearised at ``xlin`` (the prior mean for the plain EKF, the mirror image of the
    prior mean for the other branch of a range-only target) and relinearised at each
    new estimate up to ``n_iter`` times (the iterated EKF, Bell & Cathey 1993: a
    Gauss-Newton search for the posterior mode), with the linearised innovation
    ``y = z - h(x_i) - H_i (x_prior - x_i)``; ``n_iter = 1`` with ``xlin = x`` is the
    plain EKF. Each range row (kind <= ``gate_kind_max``) is gated on its own marginal
    innovation at the first linearisation point (``y_i^2 / S_ii > thr`` rejects it);
    the kept rows update jointly, the covariance in Joseph form with the last ``H``.
    Writes ``acc`` (kept?), ``nis_out`` (marginal NIS) and ``inno_out`` (innovation) for
    every row; returns the log-likelihood ``log N(y; 0, S)`` at the last linearisation
    point (rejected rows count as NIS = thr). ``mean_only``: ``P`` is left as it is
    (the caller wants a linearisation point, not a posterior).
    """
    d = x.size
    m = hi - lo
    z = np.empty(m)
    zh = np.empty(m)
    H = np.empty((m, d))
    G = np.empty((m, 2))
    ok = np.empty(m, dtype=np.bool_)
    xl = xlin.copy()
    xnew = np.empty(d)
    PHt = np.zeros((d, m))
    S = np.empty((m, m))
    keep = np.empty(m, dtype=np.int64)
    mk = 0
    ll_gated = 0.0
    ll = 0.0
    yk = np.empty(m)
    for it in range(n_iter):
        _linearise(xl, kind, a, b, val, lo, hi, rx, ry, sign, z, zh, H, G, ok)
        # linearised innovation about xl: z - h(xl) - H (x_prior - xl)
        for r in range(m):
            s = 0.0
            for j in range(d):
                s += H[r, j] * (x[j] - xl[j])
            zh[r] += s
        # PHt = P H^T (d x m), S = H P H^T + G Pr G^T + N
        for i in range(d):
            for r in range(m):
                s = 0.0
                for j in range(d):
                    s += P[i, j] * H[r, j]
                PHt[i, r] = s
        for r in range(m):
            for c in range(m):
                s = 0.0
                for j in range(d):
                    s += H[r, j] * PHt[j, c]
                g = G[r, 0] * (Pr[0, 0] * G[c, 0] + Pr[0, 1] * G[c, 1]) + G[r, 1] * (
                    Pr[1, 0] * G[c, 0] + Pr[1, 1] * G[c, 1]
                )
                S[r, c] = s + g
        for r in range(m):
            i = lo + r
            S[r, r] += var[i]
            if kind[i] == 2 and r + 1 < m and kind[i + 1] == 3:
                S[r, r + 1] += cov[i]
                S[r + 1, r] += cov[i]
        if it == 0:
            # gating on the marginal innovation of each range row
            for r in range(m):
                i = lo + r
                if not ok[r]:
                    acc[i] = False
                    nis_out[i] = np.nan
                    inno_out[i] = np.nan
                    continue
                y = z[r] - zh[r]
                inno_out[i] = y
                nis = y * y / S[r, r]
                nis_out[i] = nis
                if kind[i] <= gate_kind_max and nis > thr:
                    acc[i] = False
                    ll_gated -= 0.5 * (thr + math.log(S[r, r]) + LOG_2PI)
                else:
                    acc[i] = True
                    keep[mk] = r
                    mk += 1
            if mk == 0:
                return ll_gated
        # reduced system
        Sk = np.empty((mk, mk))
        for p in range(mk):
            yk[p] = z[keep[p]] - zh[keep[p]]
            for q in range(mk):
                Sk[p, q] = S[keep[p], keep[q]]
        if not _chol_inplace(Sk, mk):
            for p in range(mk):
                acc[lo + keep[p]] = False
            return -np.inf
        L = Sk
        # w = L^-1 y ; nis = |w|^2 ; logdet = 2 sum log diag L
        w = yk[:mk].copy()
        for p in range(mk):
            s = w[p]
            for q in range(p):
                s -= L[p, q] * w[q]
            w[p] = s / L[p, p]
        nis_joint = 0.0
        logdet = 0.0
        for p in range(mk):
            nis_joint += w[p] * w[p]
            logdet += 2.0 * math.log(L[p, p])
        ll = ll_gated - 0.5 * (nis_joint + logdet + mk * LOG_2PI)
        # K^T = S^-1 (P H^T)^T : solve L L^T Kt = PHt^T (mk x d)
        Kt = np.empty((mk, d))
        for j in range(d):
            for p in range(mk):
                s = PHt[j, keep[p]]
                for q in range(p):
                    s -= L[p, q] * Kt[q, j]
                Kt[p, j] = s / L[p, p]
            for p in range(mk - 1, -1, -1):
                s = Kt[p, j]
                for q in range(p + 1, mk):
                    s -= L[q, p] * Kt[q, j]
                Kt[p, j] = s / L[p, p]
        step = 0.0
        for j in range(d):
            s = 0.0
            for p in range(mk):
                s += Kt[p, j] * yk[p]
            xnew[j] = x[j] + s
            step += (xnew[j] - xl[j]) ** 2
        if it + 1 == n_iter or step < ITER_TOL_M2:
            break
        for j in range(d):
            xl[j] = xnew[j]
    if mean_only:  # the caller needs the posterior mean only (a linearisation point)
        for j in range(d):
            x[j] = xnew[j]
        return ll
    # R = S - H P H^T on the kept rows (needed for the Joseph form)
    Rk = np.empty((mk, mk))
    for p in range(mk):
        for q in range(mk):
            s = 0.0
            for j in range(d):
                s += H[keep[p], j] * PHt[j, keep[q]]
            Rk[p, q] = S[keep[p], keep[q]] - s
    for j in range(d):
        x[j] = xnew[j]
    # Joseph form: P = A P A^T + K R K^T, A = I - K H
    A = np.empty((d, d))
    for i in range(d):
        for j in range(d):
            s = 0.0
            for p in range(mk):
                s += Kt[p, i] * H[keep[p], j]
            A[i, j] = (1.0 if i == j else 0.0) - s
    AP = np.empty((d, d))
    for i in range(d):
        for j in range(d):
            s = 0.0
            for k in range(d):
                s += A[i, k] * P[k, j]
            AP[i, j] = s
    KR = np.empty((d, mk))
    for i in range(d):
        for q in range(mk):
            s = 0.0
            for p in range(mk):
                s += Kt[p, i] * Rk[p, q]
            KR[i, q] = s
    for i in range(d):
        for j in range(i, d):
            s = 0.0
            for k in range(d):
                s += AP[i, k] * A[j, k]
            for q in range(mk):
                s += KR[i, q] * Kt[q, j]
            P[i, j] = s
            P[j, i] = s
    return ll


@njit(cache=True)
def epoch_step(
    x, P, xp, Pp, dt, e, start, kind, a, b, val, var, cov, robot_xy, robot_P, q, sign, thr,
    gate_kind_max, relock, sigma_v0, streak, acc, nis, inno, n_iter, mirror,
):  # pragma: no cover - compiled  # fmt: skip
    """Predict ``x, P`` by ``dt`` (prior into ``xp, Pp``), update with epoch ``e``'s rows
    in place; returns (log-likelihood, number of targets re-opened).

    ``mirror = (o, p_x, p_y, u_x, u_y)``: with ``o >= 0`` the update is linearised at the
    prior mean with the position block ``o:o+2`` reflected in the line through ``p``
    along the unit vector ``u`` (the other branch of a target ranged from two points;
    :func:`epoch_update`); ``o < 0``: at the prior mean. ``n_iter`` iterations.

    Lock-out breaker: when every range of a target has been gated out in ``relock``
    consecutive epochs (``streak`` counts them per target), the filter has lost it (a
    wrong start, or NLOS ranges that pulled it away). Its position variance is then
    inflated by the largest squared innovation of those ranges and its velocity variance
    by ``sigma_v0**2``, and the epoch is updated again without the gate, so it recovers
    instead of rejecting every range thereafter.
    """
    n_t = x.size // 4
    cv_predict(x, P, dt, q, xp, Pp)
    lo, hi = start[e], start[e + 1]
    x[:] = xp
    P[:, :] = Pp
    rx, ry = robot_xy[e, 0], robot_xy[e, 1]
    xlin = xp.copy()
    # iterate from where the epoch's fixes (linear rows, first in the epoch) put the
    # fixed targets, not from their prediction: two targets 0.6 m apart whose
    # predictions are off by as much (a turn) give the pair range the wrong direction,
    # and the update then lands on the mirror side (issue 18)
    n_fix = 0
    while lo + n_fix < hi and kind[lo + n_fix] >= 2:
        n_fix += 1
    if n_iter > 1 and 0 < n_fix < hi - lo:  # (n_iter = 1: the plain EKF, at the prior)
        epoch_update(
            xlin, Pp, xp, 1, kind, a, b, val, var, cov, lo, lo + n_fix, rx, ry, robot_P[e],
            sign, np.inf, gate_kind_max, acc, nis, inno, True,
        )  # fmt: skip
    o = int(mirror[0])
    if o >= 0:
        ux, uy = mirror[3], mirror[4]
        dx, dy = xlin[o] - mirror[1], xlin[o + 1] - mirror[2]
        along = dx * ux + dy * uy
        xlin[o] = mirror[1] + 2.0 * along * ux - dx
        xlin[o + 1] = mirror[2] + 2.0 * along * uy - dy
    ll = epoch_update(
        x, P, xlin, n_iter, kind, a, b, val, var, cov, lo, hi, rx, ry, robot_P[e], sign,
        thr, gate_kind_max, acc, nis, inno,
    )  # fmt: skip
    n_re = 0
    for j in range(n_t):
        n_r = 0
        n_ok = 0
        worst = 0.0
        for r in range(lo, hi):
            if kind[r] <= gate_kind_max and (b[r] == j or (kind[r] == 1 and a[r] == j)):
                if not math.isnan(nis[r]):
                    n_r += 1
                    if acc[r]:
                        n_ok += 1
                    if inno[r] * inno[r] > worst:
                        worst = inno[r] * inno[r]
        if n_r == 0:
            continue
        if n_ok > 0:
            streak[j] = 0
            continue
        streak[j] += 1
        if streak[j] >= relock:
            o = 4 * j
            Pp[o, o] += worst
            Pp[o + 1, o + 1] += worst
            Pp[o + 2, o + 2] += sigma_v0 * sigma_v0
            Pp[o + 3, o + 3] += sigma_v0 * sigma_v0
            streak[j] = 0
            n_re += 1
    if n_re > 0:
        x[:] = xp
        P[:, :] = Pp
        ll = epoch_update(
            x, P, xlin, n_iter, kind, a, b, val, var, cov, lo, hi, rx, ry, robot_P[e],
            sign, np.inf, gate_kind_max, acc, nis, inno,
        )  # fmt: skip
    return ll, n_re


@njit(cache=True)
def run_range_ekf(
    x0, P0, t0, ev_t, start, kind, a, b, val, var, cov, robot_xy, robot_P, q, sign, thr,
    gate_kind_max, relock, sigma_v0, n_iter, xs, Ps, xps, Pps, acc, nis, inno, ll, reinit,
):  # pragma: no cover - compiled  # fmt: skip
    """Filter a whole log with :func:`epoch_step`: for each epoch e, predict to ev_t[e]
    then update with its rows.

    Fills ``xs``/``Ps`` (posterior), ``xps``/``Pps`` (prior: the prediction to epoch e),
    ``acc``/``nis``/``inno`` per row, ``ll`` per epoch and ``reinit`` (targets re-opened).
    """
    d = x0.size
    x = x0.copy()
    P = P0.copy()
    xp = np.empty(d)
    Pp = np.empty((d, d))
    streak = np.zeros(d // 4, dtype=np.int64)
    no_mirror = np.array([-1.0, 0.0, 0.0, 0.0, 0.0])
    t = t0
    for e in range(ev_t.size):
        ll[e], reinit[e] = epoch_step(
            x, P, xp, Pp, ev_t[e] - t, e, start, kind, a, b, val, var, cov, robot_xy,
            robot_P, q, sign, thr, gate_kind_max, relock, sigma_v0, streak, acc, nis, inno,
            n_iter, no_mirror,
        )  # fmt: skip
        t = ev_t[e]
        xps[e] = xp
        Pps[e] = Pp
        xs[e] = x
        Ps[e] = P


@njit(cache=True)
def mirror_d2(xp, Pp, line):  # pragma: no cover - compiled
    """Squared Mahalanobis distance, in the prediction's position covariance of the
    target of ``line``, from the predicted position to its mirror image."""
    o = int(line[0])
    ux, uy = line[3], line[4]
    dx, dy = xp[o] - line[1], xp[o + 1] - line[2]
    cr = 2.0 * (ux * dy - uy * dx)  # mirror - position = -cr * (-uy, ux)
    vx, vy = cr * uy, -cr * ux
    a, b, c = Pp[o, o], Pp[o, o + 1], Pp[o + 1, o + 1]
    det = a * c - b * b
    if not det > 0.0:
        return 0.0
    return (c * vx * vx - 2.0 * b * vx * vy + a * vy * vy) / det


@njit(cache=True)
def _same_mode(x1, x2, n_t, merge_m, merge_mps):  # pragma: no cover - compiled
    """Every target's position within merge_m and velocity within merge_mps."""
    for t in range(n_t):
        o = 4 * t
        if math.hypot(x1[o] - x2[o], x1[o + 1] - x2[o + 1]) >= merge_m:
            return False
        if math.hypot(x1[o + 2] - x2[o + 2], x1[o + 3] - x2[o + 3]) >= merge_mps:
            return False
    return True


@njit(cache=True)
def run_bank(
    X0, P0, e0, t_s, start, kind, a, b, val, var, cov, robot_xy, robot_P, q, sign, thr,
    gate_kind_max, relock, sigma_v0, n_iter, lines, n_lines, n_keep, merge_m, merge_mps,
    skip_d2, acc, nis, inno, hx, hP, hxp, hPp, hparent, hll, hcum, hmirror, hnre, hcount,
    hacc, hnis, mx, mP, mpb,
):  # pragma: no cover - compiled  # fmt: skip
    """The hypothesis bank of :func:`rangekit.localize.range_ekf._run_bank` in one call.

    Epochs ``e0 + k``, k = 0..n-1. Each hypothesis is stepped (:func:`epoch_step`) once
    per line of ``lines[k, :n_lines[k]]`` (line 0: the prediction itself, the others
    the mirror lines; a mirror line is skipped when its image lies more than
    ``sqrt(skip_d2)`` prediction sigmas away, :func:`mirror_d2`), candidates are ordered
    by cumulative log-likelihood (stable), those reaching the same mode as a better one
    (:func:`_same_mode`) add their weight to it (log-sum-exp), the ``n_keep`` heaviest
    survive, sorted by weight. Fills, per
    epoch and kept slot: the history ``hx, hP, hxp, hPp`` (posterior, prediction),
    ``hparent`` (slot at the epoch before), ``hll`` (the epoch's log-likelihood),
    ``hcum``, ``hmirror`` (updated on a mirror line), ``hnre``, ``hacc``/``hnis`` (the
    epoch's rows), ``hcount`` (slots used) and the bank as a mixture ``mx, mP`` with the
    branch probability ``mpb`` of every target (of the heaviest hypothesis:
    :func:`_mixture_into`).
    """
    n = hx.shape[0]
    d = X0.shape[1]
    n_t = d // 4
    n_h = X0.shape[0]
    max_c = max(n_h, n_keep) * lines.shape[1]
    bx = X0.copy()
    bP = P0.copy()
    bstreak = np.zeros((max(n_h, n_keep), n_t), dtype=np.int64)
    bcum = np.zeros(max(n_h, n_keep))
    nb = n_h
    cx = np.empty((max_c, d))
    cP = np.empty((max_c, d, d))
    cxp = np.empty((max_c, d))
    cPp = np.empty((max_c, d, d))
    cstreak = np.empty((max_c, n_t), dtype=np.int64)
    ccum = np.empty(max_c)
    cll = np.empty(max_c)
    cnre = np.empty(max_c, dtype=np.int64)
    cpar = np.empty(max_c, dtype=np.int64)
    cmir = np.empty(max_c, dtype=np.bool_)
    n_rows = hacc.shape[2]
    cacc = np.empty((max_c, n_rows), dtype=np.bool_)
    cnis = np.empty((max_c, n_rows))
    kept = np.empty(n_keep, dtype=np.int64)
    kcum = np.empty(n_keep)
    x = np.empty(d)
    P = np.empty((d, d))
    xp = np.empty(d)
    Pp = np.empty((d, d))
    t = t_s[e0]
    for k in range(n):
        e = e0 + k
        dt = t_s[e] - t
        t = t_s[e]
        lo, hi = start[e], start[e + 1]
        nc = 0
        for h in range(nb):
            c_direct = nc
            for li in range(n_lines[k]):
                if li > 0 and mirror_d2(cxp[c_direct], cPp[c_direct], lines[k, li]) > skip_d2:
                    continue  # that branch's weight is below exp(-skip_d2 / 2) of this one
                x[:] = bx[h]
                P[:, :] = bP[h]
                cstreak[nc] = bstreak[h]
                ll, n_re = epoch_step(
                    x, P, xp, Pp, dt, e, start, kind, a, b, val, var, cov, robot_xy,
                    robot_P, q, sign, thr, gate_kind_max, relock, sigma_v0, cstreak[nc],
                    acc, nis, inno, n_iter, lines[k, li],
                )  # fmt: skip
                cx[nc] = x
                cP[nc] = P
                cxp[nc] = xp
                cPp[nc] = Pp
                cll[nc] = ll
                ccum[nc] = bcum[h] + ll
                cnre[nc] = n_re
                cpar[nc] = h if k > 0 else -1
                cmir[nc] = li > 0
                for r in range(hi - lo):
                    cacc[nc, r] = acc[lo + r]
                    cnis[nc, r] = nis[lo + r]
                nc += 1
        order = np.argsort(-ccum[:nc], kind="mergesort")
        nk = 0
        for c in order:
            merged = False
            for i in range(nk):
                if _same_mode(cx[c], cx[kept[i]], n_t, merge_m, merge_mps):
                    hi_, lo_ = max(kcum[i], ccum[c]), min(kcum[i], ccum[c])
                    kcum[i] = hi_ + math.log1p(math.exp(lo_ - hi_))
                    merged = True
                    break
            if not merged and nk < n_keep:
                kept[nk] = c
                kcum[nk] = ccum[c]
                nk += 1
        srt = np.argsort(-kcum[:nk], kind="mergesort")
        hcount[k] = nk
        for s in range(nk):
            c = kept[srt[s]]
            hx[k, s] = cx[c]
            hP[k, s] = cP[c]
            hxp[k, s] = cxp[c]
            hPp[k, s] = cPp[c]
            hparent[k, s] = cpar[c]
            hll[k, s] = cll[c]
            hcum[k, s] = kcum[srt[s]]
            hmirror[k, s] = cmir[c]
            hnre[k, s] = cnre[c]
            for r in range(hi - lo):
                hacc[k, s, r] = cacc[c, r]
                hnis[k, s, r] = cnis[c, r]
        for s in range(nk):
            bx[s] = hx[k, s]
            bP[s] = hP[k, s]
            bstreak[s] = cstreak[kept[srt[s]]]
            bcum[s] = hcum[k, s]
        nb = nk
        _mixture_into(hx[k], hP[k], hcum[k], nk, n_t, mx[k], mP[k], mpb[k], lines[k], n_lines[k])


@njit(cache=True)
def _mixture_into(X, P, cum, nk, n_t, xbar, Pbar, pb, lines, n_lines):  # pragma: no cover
    """The bank's moments as a Gaussian mixture and the branch probability of the
    heaviest hypothesis (slot 0); :func:`rangekit.localize.range_ekf._mixture` and
    :func:`~rangekit.localize.range_ekf._branch_probability` (``lines[1:n_lines]``: the
    epoch's mirror lines)."""
    d = X.shape[1]
    w = np.empty(nk)
    top = cum[0]
    for i in range(nk):
        top = max(top, cum[i])
    tot = 0.0
    for i in range(nk):
        w[i] = math.exp(cum[i] - top)
        tot += w[i]
    for i in range(nk):
        w[i] /= tot
    for j in range(d):
        s = 0.0
        for i in range(nk):
            s += w[i] * X[i, j]
        xbar[j] = s
    for r in range(d):
        for c in range(d):
            s = 0.0
            for i in range(nk):
                s += w[i] * (P[i, r, c] + (X[i, r] - xbar[r]) * (X[i, c] - xbar[c]))
            Pbar[r, c] = s
    for r in range(d):
        for c in range(r + 1, d):
            v = 0.5 * (Pbar[r, c] + Pbar[c, r])
            Pbar[r, c] = v
            Pbar[c, r] = v
    for t in range(n_t):
        o = 4 * t
        li = -1
        for m in range(1, n_lines):
            if int(lines[m, 0]) == o:
                li = m
                break
        if li > 0:  # the mass on the reported hypothesis's side of the mirror line
            px, py, nx, ny = lines[li, 1], lines[li, 2], -lines[li, 4], lines[li, 3]
            sgn = 1.0 if (X[0, o] - px) * nx + (X[0, o + 1] - py) * ny >= 0 else -1.0
            s = 0.0
            for i in range(nk):
                dist = (X[i, o] - px) * nx + (X[i, o + 1] - py) * ny
                v = (
                    nx * nx * P[i, o, o]
                    + 2 * nx * ny * P[i, o, o + 1]
                    + ny * ny * P[i, o + 1, o + 1]
                )
                sig = math.sqrt(max(v, 1e-24))
                s += w[i] * 0.5 * math.erfc(-sgn * dist / sig / math.sqrt(2.0))
            pb[t] = s
            continue
        sig = math.sqrt(max(0.5 * (P[0, o, o] + P[0, o + 1, o + 1]), 0.0))
        rad = max(1.0, 3.0 * sig)
        s = 0.0
        for i in range(nk):
            if math.hypot(X[i, o] - X[0, o], X[i, o + 1] - X[0, o + 1]) <= rad:
                s += w[i]
        pb[t] = s
