"""The timesteps of one turn of a Fresnel program, optimised in compiled code ([2] §2.5, eq. 15).

Per turn of K steps the timesteps T minimise the largest relative acceleration max |a/a_lim|
(eq. 14) over the four axes with their sum held at K·T0. The max is replaced by a p-norm,
smooth enough for a quasi-Newton method, and T is parametrised as K·T0·softmax(u), so that
the sum always holds and no step can reach zero (no step shorter than e^-20 of the longest).

:func:`minimise_turn` is a limited-memory BFGS (the two-loop recursion, ten pairs, the initial
inverse Hessian scaled by s·y/y·y) with a line search for the strong Wolfe conditions
(sufficient decrease 1e-3, curvature 0.9, cubic interpolation in the bracket): the method and
the stopping rules of SciPy's L-BFGS-B without bounds (a relative decrease of at most
``ftol`` in an iteration, or a largest gradient component ≤ ``gtol``), run wholly inside one
compiled call instead of returning to Python at every evaluation. Its iterates are not
SciPy's (another line search), so the optimum it ends on differs within the optimiser's
accuracy (tests/kinds/test_fresnel.py: every checked turn within 5 % of a direct minimax).

Times s, accelerations relative to their limits.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from ftsweep.stages.paths.fresnel import _turn_relative_into

# strong Wolfe constants and the evaluations one line search may take (SciPy's L-BFGS-B: 1e-3,
# 0.9 and 20)
C1 = 1e-3
C2 = 0.9
MAX_LINE_EVALS = 20
MEMORY = 10
# p-norm exponents that are powers of two up to 2^MAX_SQUARINGS are raised by squaring
MAX_SQUARINGS = 12
TINY = 1e-290


@njit(nogil=True, cache=True, inline="always")
def _weight(x: float, power: float, squarings: int) -> float:  # pragma: no cover - jit
    """x^(p−1) for x > 0: where p = 2^squarings (``squarings`` > 0) x^p by squaring and one
    division, a few cycles where pow() costs tens; pow() otherwise."""
    if squarings <= 0:
        return x ** (power - 1.0)
    xp = x
    for _ in range(squarings):
        xp *= xp
    return xp / x


@njit(nogil=True, cache=True, inline="always")
def _squarings_of(power: float) -> int:  # pragma: no cover - jit
    """n where power = 2^n (1 ≤ n ≤ MAX_SQUARINGS), else 0."""
    p = 2.0
    for n in range(1, MAX_SQUARINGS + 1):
        if power == p:
            return n
        p *= 2.0
    return 0


@njit(nogil=True, cache=True)
def softmax_steps(u: np.ndarray, total: float) -> np.ndarray:  # pragma: no cover - jit
    """Timesteps T = total·softmax(u) [s] of a turn, no step shorter than e^-20 of the longest
    (which keeps a line search off T = 0)."""
    out = np.empty(u.size)
    _softmax_into(u, total, out)
    return out


@njit(nogil=True, cache=True, inline="always")
def _softmax_into(u: np.ndarray, total: float, out: np.ndarray) -> None:  # pragma: no cover - jit
    top = u.max()
    norm = 0.0
    for i in range(u.size):
        out[i] = math.exp(max(u[i] - top, -20.0))
        norm += out[i]
    for i in range(u.size):
        out[i] = total * out[i] / norm


@njit(nogil=True, cache=True)
def turn_cost_into(
    steps: np.ndarray,
    deltas: np.ndarray,
    inv_limit: np.ndarray,
    power: float,
    first: bool,
    rel: np.ndarray,
    weight: np.ndarray,
    grad: np.ndarray,
) -> float:  # pragma: no cover - jit
    """Log of the p-norm of the relative accelerations |a/a_lim| over one turn ([2] eq. 15,
    its max replaced by the p-norm) and, into ``grad`` (K,), its gradient with respect to the
    K timesteps; ``rel`` and ``weight`` (K + 1, A) are scratch.

    steps : (K,) T_k [s]. deltas : (K + 1, A) position differences, row 0 the step into the
    turn's first point, taken with the turn's own last timestep. inv_limit : (A,) 1/a_lim.
    first : the program's first turn (its first point has no acceleration)."""
    k_n = steps.size
    m = deltas.shape[1]
    big = _turn_relative_into(steps, deltas, inv_limit, first, rel)
    grad[:] = 0.0
    if big == 0.0:
        return 0.0
    squarings = _squarings_of(power)
    inv_big = 1.0 / big
    # below it x^p < 1e-290 adds nothing to the sum (≥ 1, the largest term is 1): such terms are
    # left out rather than computed in subnormal arithmetic, ~100× slower per operation
    cutoff = TINY ** (1.0 / power)
    total = 0.0
    for k in range(k_n):
        for j in range(m):
            x = abs(rel[k, j]) * inv_big
            # x^(p-1) is what the gradient needs; x^p = x^(p-1)·x
            xp = _weight(x, power, squarings) if x > cutoff else 0.0
            weight[k, j] = xp
            total += xp * x
    scale = inv_big / total
    # one division per step, none per axis: the loop runs K·A times per evaluation
    for k in range(k_n):
        if first and k == 0:
            continue
        before = k - 1 if k > 0 else k_n - 1
        inv_t0 = 1.0 / steps[before]
        inv_t1 = 1.0 / steps[k]
        inv_s = 1.0 / (steps[before] + steps[k])
        g_k = 0.0
        g_before = 0.0
        for j in range(m):
            r = rel[k, j]
            if r == 0.0:
                continue
            w = math.copysign(weight[k, j], r) * scale * inv_s
            g_k += w * (-2.0 * deltas[k + 1, j] * inv_t1 * inv_t1 * inv_limit[j] - r)
            g_before += w * (2.0 * deltas[k, j] * inv_t0 * inv_t0 * inv_limit[j] - r)
        grad[k] += g_k
        grad[before] += g_before
    return math.log(big) + math.log(total) / power


@njit(nogil=True, cache=True)
def _u_cost(
    u: np.ndarray,
    total: float,
    deltas: np.ndarray,
    inv_limit: np.ndarray,
    power: float,
    first: bool,
    work: tuple[Any, ...],
    grad_u: np.ndarray,
) -> float:  # pragma: no cover - jit
    """The cost of :func:`turn_cost_into` at T = total·softmax(u) and its gradient in u (the
    chain rule through the softmax) into ``grad_u``; ``work``: (steps, grad_T, rel, weight)."""
    steps, grad_t, rel, weight = work
    _softmax_into(u, total, steps)
    value = turn_cost_into(steps, deltas, inv_limit, power, first, rel, weight, grad_t)
    dot = 0.0
    for i in range(u.size):
        dot += grad_t[i] * steps[i]
    for i in range(u.size):
        grad_u[i] = steps[i] * (grad_t[i] - dot / total)
    return value


@njit(nogil=True, cache=True, inline="always")
def _dot(a: np.ndarray, b: np.ndarray) -> float:  # pragma: no cover - jit
    out = 0.0
    for i in range(a.size):
        out += a[i] * b[i]
    return out


@njit(nogil=True, cache=True, inline="always")
def _largest(a: np.ndarray) -> float:  # pragma: no cover - jit
    out = 0.0
    for i in range(a.size):
        out = max(out, abs(a[i]))
    return out


@njit(nogil=True, cache=True, inline="always")
def _axpy(a: float, x: np.ndarray, y: np.ndarray) -> None:  # pragma: no cover - jit
    """y += a·x in place (no temporary array)."""
    for i in range(y.size):
        y[i] += a * x[i]


@njit(nogil=True, cache=True)
def _direction(
    g: np.ndarray,
    s_mem: np.ndarray,
    y_mem: np.ndarray,
    rho: np.ndarray,
    alpha: np.ndarray,
    count: int,
    newest: int,
    d: np.ndarray,
) -> None:  # pragma: no cover - jit
    """d = −H·g by the two-loop recursion over the ``count`` stored pairs (``newest`` the last
    written row), H0 = s·y/y·y of the newest pair."""
    memory = rho.size
    for i in range(g.size):
        d[i] = -g[i]
    for i in range(count):
        j = (newest - i) % memory
        alpha[j] = rho[j] * _dot(s_mem[j], d)
        _axpy(-alpha[j], y_mem[j], d)
    if count > 0:
        gamma = 1.0 / (rho[newest] * _dot(y_mem[newest], y_mem[newest]))
        for i in range(d.size):
            d[i] *= gamma
    for i in range(count - 1, -1, -1):
        j = (newest - i) % memory
        beta = rho[j] * _dot(y_mem[j], d)
        _axpy(alpha[j] - beta, s_mem[j], d)


@njit(nogil=True, cache=True, inline="always")
def _trial_step(
    a_lo: float, f_lo: float, d_lo: float, a_hi: float, f_hi: float, d_hi: float
) -> float:  # pragma: no cover - jit
    """The next trial step inside the bracket [a_lo, a_hi]: the minimiser of the cubic through
    both ends' values and slopes, kept a tenth of the bracket away from its ends (bisection
    where the cubic has none)."""
    width = a_hi - a_lo
    d1 = d_lo + d_hi - 3.0 * (f_lo - f_hi) / (a_lo - a_hi)
    disc = d1 * d1 - d_lo * d_hi
    if disc >= 0.0 and math.isfinite(disc):
        d2 = math.copysign(math.sqrt(disc), a_hi - a_lo)
        den = d_hi - d_lo + 2.0 * d2
        if den != 0.0:
            t = a_hi - width * (d_hi + d2 - d1) / den
            lo, hi = min(a_lo, a_hi), max(a_lo, a_hi)
            margin = 0.1 * abs(width)
            if lo + margin <= t <= hi - margin:
                return t
    return a_lo + 0.5 * width


@njit(nogil=True, cache=True, inline="always")
def _next_step(
    a: float, a_lo: float, f_lo: float, d_lo: float, a_hi: float, f_hi: float, d_hi: float
) -> float:  # pragma: no cover - jit
    """The next trial step of :func:`_line_search`: extrapolated while no upper end brackets
    the minimiser, halved towards an upper end of non-finite cost, else interpolated."""
    if math.isnan(a_hi):
        return 4.0 * a  # still descending: extrapolate
    if not math.isfinite(f_hi):
        return a_lo + 0.5 * (a_hi - a_lo)
    return _trial_step(a_lo, f_lo, d_lo, a_hi, f_hi, d_hi)


@njit(nogil=True, cache=True)
def _line_search(
    x: np.ndarray,
    f0: float,
    gd0: float,
    d: np.ndarray,
    a: float,
    args: tuple[Any, ...],
    work: tuple[Any, ...],
    trial: tuple[Any, ...],
    best: tuple[Any, ...],
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """A step along ``d`` from ``x`` (cost f0, slope gd0 < 0) meeting the strong Wolfe
    conditions, starting with step ``a``. ``trial`` and ``best`` are (u, grad) pairs of
    scratch; on return ``best`` holds the point taken. Returns (taken: False
    False when no step of sufficient decrease was found in :data:`MAX_LINE_EVALS` evaluations),
    its cost and the evaluations it took."""
    total, deltas, inv_limit, power, first = args
    xt, gt = trial
    xb, gb = best
    a_lo, f_lo, d_lo = 0.0, f0, gd0
    a_hi, f_hi, d_hi = math.nan, math.nan, math.nan
    for evals in range(1, MAX_LINE_EVALS + 1):
        for i in range(x.size):
            xt[i] = x[i] + a * d[i]
        ft = _u_cost(xt, total, deltas, inv_limit, power, first, work, gt)
        dt = _dot(gt, d)
        if not math.isfinite(ft) or ft > f0 + C1 * a * gd0 or ft >= f_lo:
            a_hi, f_hi, d_hi = a, ft, dt  # too far: the minimiser lies before a
        else:
            xb[:] = xt
            gb[:] = gt
            if abs(dt) <= -C2 * gd0:
                return True, ft, evals
            if math.isnan(a_hi):
                if dt >= 0.0:
                    a_hi, f_hi, d_hi = a_lo, f_lo, d_lo
            elif dt * (a_hi - a_lo) >= 0.0:
                a_hi, f_hi, d_hi = a_lo, f_lo, d_lo
            a_lo, f_lo, d_lo = a, ft, dt
        a = _next_step(a, a_lo, f_lo, d_lo, a_hi, f_hi, d_hi)
        if abs(a - a_lo) <= 1e-15 * max(abs(a_lo), 1e-300):
            break
    return a_lo > 0.0, f_lo, evals


@njit(nogil=True, cache=True)
def minimise_turn(
    u0: np.ndarray,
    total: float,
    deltas: np.ndarray,
    inv_limit: np.ndarray,
    first: bool,
    power: float,
    max_iter: int,
    ftol: float,
    gtol: float,
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Minimise the p-norm cost of one turn over u (T = total·softmax(u)), from ``u0``, by
    L-BFGS with strong-Wolfe line searches (module docstring) for at most ``max_iter``
    iterations; stops when an iteration lowers the cost by at most ``ftol`` relative to
    max(|f|, 1) or the largest gradient component is ≤ ``gtol``. Returns (u, iterations,
    evaluations of the cost)."""
    n = u0.size
    args = (total, deltas, inv_limit, power, first)
    work = (np.empty(n), np.empty(n), np.empty(deltas.shape), np.empty(deltas.shape))
    x, g = u0.copy(), np.empty(n)
    trial = (np.empty(n), np.empty(n))
    best = (np.empty(n), np.empty(n))
    s_mem, y_mem = np.zeros((MEMORY, n)), np.zeros((MEMORY, n))
    rho, alpha, d = np.zeros(MEMORY), np.zeros(MEMORY), np.empty(n)
    count, newest = 0, MEMORY - 1
    f = _u_cost(x, total, deltas, inv_limit, power, first, work, g)
    it, evals = 0, 1
    while it < max_iter and _largest(g) > gtol:
        _direction(g, s_mem, y_mem, rho, alpha, count, newest, d)
        gd = _dot(g, d)
        if gd >= 0.0:  # not a descent direction (rounding): start again from the gradient
            count = 0
            d[:] = -g
            gd = -_dot(g, g)
        a0 = 1.0 if count > 0 else min(1.0 / math.sqrt(_dot(d, d)), 1e10)
        taken, f_new, used = _line_search(x, f, gd, d, a0, args, work, trial, best)
        evals += used
        if not taken:
            if count == 0:
                break  # not even along the gradient: as low as this precision allows
            count = 0  # forget the curvature pairs and try again from the gradient
            continue
        xb, gb = best
        newest = (newest + 1) % MEMORY
        for i in range(n):
            s_mem[newest, i] = xb[i] - x[i]
            y_mem[newest, i] = gb[i] - g[i]
        sy = _dot(s_mem[newest], y_mem[newest])
        if sy > -2.2e-16 * _dot(g, s_mem[newest]):
            rho[newest] = 1.0 / sy
            count = min(count + 1, MEMORY)
        else:  # no curvature information in this step: the pair is not kept
            newest = (newest - 1) % MEMORY
        x[:] = xb
        g[:] = gb
        it += 1
        if f - f_new <= ftol * max(abs(f), abs(f_new), 1.0):
            break
        f = f_new
    return x, it, evals
