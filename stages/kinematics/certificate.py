"""A lower bound on the least time of any program through fixed points within its axes'
limits: the certificate of :mod:`.timing`'s fastest profile (docs/kinds.md "Time-optimal
timing"; the inequalities and pair caps of :mod:`.timing`, [2] eq. 14).

*Relaxation for a class.* Give every step k a length θ_k [s] and consider first the programs
none of whose steps is longer (s ≥ σ = 1/θ). Replace each point's inequalities by the pairs
(x, y) with y ≤ U(x) and x ≤ W(y), U(x) = sup{y : some x' in [σ_{k−1}, x] meets the point with
y}, W likewise: a superset of the feasible pairs. U and W increase, so the profiles meeting all
of them and the speed caps form a lattice whose greatest element ŝ bounds every step's speed
in the class. Passes from the caps that only ever lower a speed to U or W of its neighbour
stay above ŝ whenever they stop (:func:`bound`), and each s_k stays at least the least of its
cap, U(s_{k−1}) and W(s_{k+1}) (its *pointer* is the least one).

*Every program.* A step longer than θ_k (a *long* step) falls outside the class. For a program
with long steps L, the other steps' speeds meet the relaxation with the points next to L
dropped. A step i whose pointers lead (the *chain* of pairs they pass, its *span*) to a cap
or to a pair that settles alone without passing a point next to L keeps s_i ≤ s_i of the
passes, by induction along the chain; the others lose at most g_i = 1/s_i − 1/cap_i. A long
step k is itself at least θ_k. So the program's time is at least
Σ 1/s_i + Σ_{k in L} (θ_k − 1/s_k − G_k), G_k = Σ g_i over the chains spanning k. A long step
also caps its neighbours: over a step of T, an axis's velocity can change by at most
A·(T + T_neighbour)/2, so up to a length τ*_k it holds both neighbours at or below the passes'
speeds and releases nothing (:func:`_hold`); only a step longer than max(θ_k, τ*_k) can
release. Where max(θ_k, τ*_k) ≥ M_k = 1/s_k + G_k at every step, Σ 1/s_i bounds every
program. θ starts at the caller's θ and is raised to 1.05·M_k where a step fails, for a few
rounds; what still fails is subtracted, Σ max(0, M_k − max(θ_k, τ*_k)). A pair whose chains
end on each other is checked by iterating the pair alone from its caps until it is at or
below the passes' speeds (else its chains' g are subtracted). Speeds are divided by 1 + 1e-9
against rounding (U(λx) ≤ λU(x) for λ ≥ 1 carries the slack along a chain).

A block of steps (a facet) is bounded the same way with its own steps, less the g of its
steps whose chains leave it (:func:`block_bounds`).

Units: positions in SI (m, rad), speeds 1/s, times s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ftsweep.stages.kinematics.timing import SHORTEST_S, pair_x_cap, pair_y_cap, speed_caps

# the passes' count: the bound they give is valid after any number; after 10 it is within
# 2.4e-4 of its limit on the Fresnel example (274.59 against 274.65 s), in half the time of 20
# (5.8 s on the 1.85 M-point part); the rounds that raise θ where a long step could pay
PASSES = 10
ROUNDS = 6
RAISE = 1.05
SLACK = 1e-9
# iterations a pair whose chains end on each other may take to come below the passes
PAIR_ITERATIONS = 5000


@njit(nogil=True, cache=True)
def bound(
    d: np.ndarray, cap: np.ndarray, accel: np.ndarray, sigma: np.ndarray, passes: int
) -> np.ndarray:  # pragma: no cover - jit
    """Speeds s (P − 1) [1/s] above the greatest profile of the relaxation (module docstring)
    with σ_k = ``sigma`` [1/s]: ``passes`` forward-backward passes from the caps."""
    n = cap.size
    s = cap.copy()
    for _ in range(passes):
        for i in range(1, n):
            s[i] = pair_y_cap(d[i - 1], d[i], s[i - 1], accel, s[i], sigma[i - 1])
        for i in range(n - 1, 0, -1):
            s[i - 1] = pair_x_cap(d[i - 1], d[i], s[i], accel, s[i - 1], sigma[i])
    return s


@njit(nogil=True, cache=True)
def _pointers(
    d: np.ndarray, cap: np.ndarray, accel: np.ndarray, sigma: np.ndarray, s: np.ndarray
) -> np.ndarray:  # pragma: no cover - jit
    """0 where a step's least bound is its cap, 1 its left pair's U, 2 its right pair's W."""
    n = s.size
    out = np.zeros(n, dtype=np.int8)
    for i in range(n):
        best = cap[i]
        if i > 0:
            left = pair_y_cap(d[i - 1], d[i], s[i - 1], accel, math.inf, sigma[i - 1])
            if left < best:
                best = left
                out[i] = 1
        if i < n - 1 and pair_x_cap(d[i], d[i + 1], s[i + 1], accel, math.inf, sigma[i + 1]) < best:
            out[i] = 2
    return out


@njit(nogil=True, cache=True)
def _spans(ptr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - jit
    """Per step, the first and last step its chain touches, and the left step of the pair its
    chain ends on when that pair's pointers face each other (else −1)."""
    n = ptr.size
    lo, hi = np.arange(n), np.arange(n)
    end = np.full(n, -1)
    for i in range(n):
        j = i
        if ptr[i] == 1:
            while j > 0 and ptr[j] == 1:
                j -= 1
                if ptr[j] == 2:
                    end[i] = j
                    break
            lo[i] = j
        elif ptr[i] == 2:
            while j < n - 1 and ptr[j] == 2:
                j += 1
                if ptr[j] == 1:
                    end[i] = j - 1
                    break
            hi[i] = j
    return lo, hi, end


@njit(nogil=True, cache=True)
def _settles(
    d: np.ndarray, cap: np.ndarray, accel: np.ndarray, sigma: np.ndarray, s: np.ndarray, j: int
) -> bool:  # pragma: no cover - jit
    """Whether the pair of steps j, j + 1 iterated alone from its caps comes at or below the
    passes' speeds (within SLACK) in PAIR_ITERATIONS."""
    x, y = cap[j], cap[j + 1]
    for _ in range(PAIR_ITERATIONS):
        y = pair_y_cap(d[j], d[j + 1], x, accel, y, sigma[j])
        x = pair_x_cap(d[j], d[j + 1], y, accel, x, sigma[j + 1])
        if x <= s[j] * (1.0 + SLACK) and y <= s[j + 1] * (1.0 + SLACK):
            return True
    return False


@njit(nogil=True, cache=True)
def _release(
    d: np.ndarray,
    cap: np.ndarray,
    accel: np.ndarray,
    sigma: np.ndarray,
    s: np.ndarray,
    gain: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    end: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - jit
    """G_k (P − 1) [s]: the g_i (``gain``) of the chains spanning each step, and whether each
    step's chain is settled (else it ends on a pair that does not come below the passes alone)."""
    n = s.size
    settled = np.ones(n, dtype=np.bool_)
    checked = np.zeros(n, dtype=np.int8)  # 0 unseen, 1 settles, 2 does not
    edge = np.zeros(n + 1)
    for i in range(n):
        g = gain[i]
        j = end[i]
        if j >= 0:
            if checked[j] == 0:
                checked[j] = 1 if _settles(d, cap, accel, sigma, s, j) else 2
            if checked[j] == 2:
                settled[i] = False
                continue
        edge[lo[i]] += g
        edge[hi[i] + 1] -= g
    out = np.empty(n)
    run = 0.0
    for k in range(n):
        run += edge[k]
        out[k] = run
    return out, settled


@njit(nogil=True, cache=True)
def _hold(
    d: np.ndarray, accel: np.ndarray, theta: np.ndarray, s: np.ndarray
) -> np.ndarray:  # pragma: no cover - jit
    """τ*_k [s]: the longest step k up to which, from θ_k on, one of the axes' inequalities at
    each of its points holds its neighbour at or below the passes' speed ``s`` (module
    docstring); θ_k where none does. A step of T caps its right neighbour through an
    inequality with α > 0 at root(β/T + c·T) ≤ s_{k+1} while c·T² − K·T + β ≤ 0,
    K = α·s_{k+1} − c/s_{k+1}, and its left neighbour likewise."""
    n, m = d.shape
    out = np.empty(n)
    for k in range(n):
        hold = math.inf
        for side in (1, -1):
            nb = k + side
            if nb < 0 or nb >= n:
                continue
            best = theta[k]
            for j in range(m):
                if not accel[j] < math.inf:
                    continue
                c = 0.5 * accel[j]
                for sign in (1.0, -1.0):
                    # the neighbour's coefficient and the long step's, as c·T² − K·T + a_k ≤ 0
                    flip = sign * side
                    a_nb, a_k = flip * d[nb, j], flip * d[k, j]
                    if a_nb <= 0.0:
                        continue
                    big_k = a_nb * s[nb] - c / s[nb]
                    disc = big_k * big_k - 4.0 * c * a_k
                    if disc < 0.0 or a_k / theta[k] + c * theta[k] > big_k:
                        continue
                    best = max(best, (big_k + math.sqrt(disc)) / (2.0 * c))
            hold = min(hold, best)
        out[k] = hold
    return out


class LeastTimeBound(NamedTuple):
    """A lower bound on the least time of every program through a program's points within
    its limits (module docstring).

    total_s : the bound [s]. step_s : (P − 1,) 1/s_k [s] of the passes (over 1 + SLACK).
    release_s : (P − 1,) g_k [s]. lo, hi : (P − 1,) the steps each chain spans.
    settled : (P − 1,) whether each step's chain is settled. longest_s : (P − 1,) θ_k [s].
    excess_s : (P − 1,) max(0, M_k − max(θ_k, τ*_k)) [s], subtracted. rounds : θ's rounds.
    """

    total_s: float
    step_s: np.ndarray
    release_s: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    settled: np.ndarray
    longest_s: np.ndarray
    excess_s: np.ndarray
    rounds: int


def least_time_bound(
    q: np.ndarray, velocity: np.ndarray, accel: np.ndarray, longest_s: float
) -> LeastTimeBound:
    """A lower bound [s] on the time of every program through positions q (P, A) SI within the
    limits ``velocity`` and ``accel`` (A,) SI (module docstring), θ starting at ``longest_s``
    [s] on every step (the longest step of a program the caller has in hand, or longer)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    d = np.ascontiguousarray(np.diff(q, axis=0))
    accel = np.ascontiguousarray(accel, dtype=np.float64)
    cap = speed_caps(d, np.ascontiguousarray(velocity, dtype=np.float64), SHORTEST_S)
    theta = np.full(cap.size, float(longest_s))
    for rounds in range(1, ROUNDS + 1):
        sigma = 1.0 / theta
        s = bound(d, cap, accel, sigma, PASSES)
        lo, hi, end = _spans(_pointers(d, cap, accel, sigma, s))
        step = 1.0 / (s * (1.0 + SLACK))
        gain = step - 1.0 / cap
        through, settled = _release(d, cap, accel, sigma, s, gain, lo, hi, end)
        need = step + through - np.where(settled, gain, 0.0)
        excess = np.maximum(need - np.maximum(theta, _hold(d, accel, theta, s)), 0.0)
        # a step whose bound exceeds θ_k would fall outside its own class
        short = step > theta
        if not (excess.any() or short.any()) or rounds == ROUNDS:
            break
        theta = np.where(excess > 0.0, RAISE * need, theta)
        theta = np.where(short, RAISE * step, theta)
    total = float(step.sum() - gain[~settled].sum() - excess.sum())
    if short.any():
        total = float((1.0 / cap).sum())  # not reached on any part measured: the speed caps alone
    return LeastTimeBound(total, step, gain, lo, hi, settled, theta, excess, rounds)


def block_bounds(b: LeastTimeBound, starts: np.ndarray) -> np.ndarray:
    """Lower bounds [s] on the time of every program over each block of consecutive steps
    from ``starts`` (sorted, the first 0) to the next: the block's own 1/s_k, less the g of
    its steps whose chains leave it or are unsettled, less its steps' excess."""
    n = b.step_s.size
    edges = np.append(np.asarray(starts, dtype=np.int64), n)
    out = np.empty(edges.size - 1)
    for m in range(out.size):
        a, z = int(edges[m]), int(edges[m + 1])
        leave = (b.lo[a:z] < a) | (b.hi[a:z] >= z) | ~b.settled[a:z]
        out[m] = b.step_s[a:z].sum() - b.release_s[a:z][leave].sum() - b.excess_s[a:z].sum()
    return out
