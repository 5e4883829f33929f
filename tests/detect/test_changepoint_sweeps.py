"""The sweeps that replaced two all-pairs loops of the beep detector give the same answer.

``_resolve_aliases`` tested every pair of groups with n x n matrices, and
``_shift_flags`` concatenated every other arrival's bursts once per arrival: quadratic in
time (and in memory, for the matrices) on an hour of beeps. The references below are
those loops as they were; the sweeps must agree with them exactly on groups built like
the detector's: beeps on a spacing grid, groups that index one beep two ways (shifted by
one or two spacings, sharing bursts), chains of them, lone groups, and groups with
missing bursts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rangekit.detect import changepoint as C

SPACING = 5000.0
TOL = 4.0


def _aliases_reference(rows: list[tuple], *, tol: float) -> list[tuple]:
    """``_resolve_aliases`` before the sweep (2026-12-03): every pair, n x n matrices."""
    n = len(rows)
    ons = [r[4][np.isfinite(r[4])] for r in rows]
    span = [(float(a.min()), float(a.max())) if len(a) else (math.inf, -math.inf) for a in ons]
    shared = np.zeros((n, n), dtype=np.int64)
    for i in range(n):
        for j in range(i + 1, n):
            if span[i][0] > span[j][1] + tol or span[j][0] > span[i][1] + tol:
                continue
            a, b = ons[i], ons[j]
            k = int(np.sum(np.min(np.abs(a[:, None] - b[None, :]), axis=1) <= tol))
            shared[i, j] = shared[j, i] = k
    onset = np.array([r[0] for r in rows])
    alias = (shared >= 2) & (np.abs(onset[:, None] - onset[None, :]) > tol)
    strength = [float(r[6]) for r in rows]
    keep = [True] * n
    seen = [False] * n
    for start in range(n):
        if seen[start] or not alias[start].any():
            continue
        comp, todo = [], [start]
        seen[start] = True
        while todo:
            i = todo.pop()
            comp.append(i)
            for j in np.flatnonzero(alias[i]).tolist():
                if not seen[j]:
                    seen[j] = True
                    todo.append(j)
        comp.sort()
        if len(comp) <= C.ALIAS_SET_MAX:
            best, best_s = 0, -math.inf
            for m in range(1, 1 << len(comp)):
                sel = [comp[t] for t in range(len(comp)) if m >> t & 1]
                if any(shared[i, j] for i in sel for j in sel if i < j):
                    continue
                tot = sum(strength[i] for i in sel)
                if tot > best_s:
                    best, best_s = m, tot
            for t, i in enumerate(comp):
                keep[i] = bool(best >> t & 1)
            continue
        for i in comp:
            for j in comp:
                if i < j and keep[i] and keep[j] and alias[i, j]:
                    keep[i if strength[i] < strength[j] else j] = False
    return [r for r, k in zip(rows, keep, strict=True) if k]


def _groups(rng: np.random.Generator, n_beeps: int, k: int = 4) -> list[tuple]:
    """Rows shaped like the detector's (onset, ..., burst onsets, ..., strength)."""
    rows = []
    t = 1000.0
    for _ in range(n_beeps):
        # beeps close enough at times to chain (the next one on the previous one's grid)
        t += SPACING * (k + rng.choice([0.0, 1.0, 3.0, 40.0], p=[0.15, 0.15, 0.2, 0.5]))
        grid = t + SPACING * np.arange(k)
        rows.append(grid + rng.uniform(-1, 1, k))
        for shift in rng.choice([-2, -1, 1, 2], size=rng.integers(0, 3), replace=False):
            b = grid + shift * SPACING + rng.uniform(-1.5 * TOL, 1.5 * TOL, k)
            b[rng.random(k) < 0.2] = np.nan  # a burst the group did not find
            rows.append(b)
        if rng.random() < 0.1:
            rows.append(np.full(k, np.nan))  # a group without a finite burst
    out = []
    for b in rows:
        fin = b[np.isfinite(b)]
        onset = float(fin[0]) if len(fin) else float(t)
        out.append((onset, None, None, None, b, None, float(rng.uniform(1.0, 10.0))))
    rng.shuffle(out)
    return out


@pytest.mark.parametrize("seed", range(12))
def test_alias_sweep_keeps_what_every_pair_kept(seed):
    rng = np.random.default_rng(seed)
    rows = _groups(rng, n_beeps=int(rng.integers(5, 60)))
    got = C._resolve_aliases(rows, tol=TOL)
    want = _aliases_reference(rows, tol=TOL)
    assert [id(r) for r in got] == [id(r) for r in want]
    # the case is not trivial: some groups are dropped as aliases, most are kept
    assert 0 < len(rows) - len(got) < len(rows)


def test_alias_sweep_on_a_long_chain_resolves_pair_by_pair_like_the_reference():
    """More than ``ALIAS_SET_MAX`` linked groups: the pair-by-pair rule, same as before."""
    rng = np.random.default_rng(5)
    grid = 1000.0 + SPACING * np.arange(C.ALIAS_SET_MAX + 6)
    rows = [
        (float(grid[s]), None, None, None, grid[s : s + 4] + rng.uniform(-1, 1, 4), None,
         float(rng.uniform(1, 10)))
        for s in range(len(grid) - 3)
    ]  # fmt: skip
    got = C._resolve_aliases(rows, tol=TOL)
    assert [id(r) for r in got] == [id(r) for r in _aliases_reference(rows, tol=TOL)]
    assert len(got) < len(rows)


def test_alias_sweep_memory_is_not_quadratic_in_the_groups():
    """4000 lone beeps (about an hour of exchanges in one channel): the pairs loop held
    three 4000 x 4000 matrices (tracemalloc peak 401 MB, 7.7 s); the sweep none."""
    import tracemalloc

    ts = 1000.0 + 20 * SPACING * np.arange(4000)
    rows = [(float(t), None, None, None, t + SPACING * np.arange(4), None, 1.0) for t in ts]
    tracemalloc.start()
    try:
        kept = C._resolve_aliases(rows, tol=TOL)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(kept) == 4000
    assert peak < 3.2e6  # measured 1.59 MB (the burst arrays and the sorted order)


@pytest.mark.parametrize("seed", range(6))
def test_other_burst_near_is_the_brute_force_test(seed):
    """``_other_burst_near`` is ``min |b - place| <= tol`` over the other arrivals' bursts,
    at places on, just inside and just outside ``tol`` of a burst."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(2, 40))
    bursts = [1e4 * i + SPACING * np.arange(4) + rng.uniform(-2, 2, 4) for i in range(n)]
    for b in bursts:
        b[rng.random(4) < 0.2] = np.nan
    fin = [b[np.isfinite(b)] for b in bursts]
    all_b = np.concatenate(fin)
    owner = np.repeat(np.arange(n), [len(b) for b in fin])
    by_t = np.argsort(all_b, kind="stable")
    all_b, owner = all_b[by_t], owner[by_t]
    tol = int(rng.integers(1, 6))
    n_near = 0
    for i in range(n):
        others = np.concatenate([b for j, b in enumerate(fin) if j != i] or [np.zeros(0)])
        near = others[rng.integers(0, len(others), 8)] if len(others) else np.zeros(0)
        edges = [near + d for d in (tol, -tol, tol + 1e-6, -tol - 1e-6, tol - 1e-6)]
        places = np.concatenate([near, *edges, rng.uniform(0, 1e4 * n, 8)])
        for place in places:
            want = bool(len(others)) and float(np.min(np.abs(others - place))) <= tol
            assert C._other_burst_near(all_b, owner, i, float(place), tol) == want
            n_near += want
    assert n_near > 0


def test_precursor_ratio_in_chunks_is_the_ratio_of_all_beeps_at_once(monkeypatch):
    """``precursor_ratio`` takes ``PRE_CHUNK`` beeps at a time (the level stretches of an
    hour of beeps at once outgrew the caches: 38 us a beep instead of 20); each row is
    its own, so chunks of 3 and all 50 at once give the same array, NaN rows included."""
    rng = np.random.default_rng(4)
    fs = 44100.0
    x = rng.standard_normal(int(40 * fs)).astype(np.float32)
    clipped = rng.random(len(x)) < 2e-5
    on = np.sort(rng.uniform(3000, len(x) - 30000, 50))[:, None] + SPACING * np.arange(4)
    on[[0, 17]] = [[-500.0], [len(x) + 10.0]]  # windows outside the recording: NaN rows
    kw = {"fs": fs, "f_hz": 16000.0, "lengths": (32, 64, 128), "guard": 8, "clipped": clipped}
    monkeypatch.setattr(C, "PRE_CHUNK", 10**6)
    whole = C.precursor_ratio(x, on, **kw)
    monkeypatch.setattr(C, "PRE_CHUNK", 3)
    chunked = C.precursor_ratio(x, on, **kw)
    assert whole.shape == (50, 3)
    np.testing.assert_array_equal(chunked, whole)
    n_nan = int(np.isnan(whole[:, 0]).sum())
    assert 2 <= n_nan < 50  # the two outside, and the clipped ones
