"""Fixed-point decimal text of doubles, digit for digit what Python's ``format(v, ".9f")``
prints, at compiled speed: the data lines of path programs (a million lines of four or five
numbers took 1.7-1.9 s through ``str.format``; here a few hundredths).

Python prints the exact binary value of a double rounded half to even at the last decimal.
The kernel does the same in integers: v = M·2^E (M < 2^53), so v·10^d = M·10^d·2^E exactly;
M·10^d (< 2^83) is formed in two int64 limbs and shifted right by −E, the bit below the last
kept one and the bits under it deciding the rounding (half to even). No step rounds, so the
digits are the exact ones; the tests compare them with Python's on random, tied and extreme
values.

A number read back from that text is the double nearest to N·10^−d (N the printed integer of
units of the last decimal); for N < 2^53 that is N/10^d computed in floating point (both exact,
one correctly rounded division), which :func:`printed` returns without parsing any text.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

# |v|·10^d must stay below this: N and the intermediate limbs fit int64 with room
LIMIT = 2.0**62
_TWO53 = 9007199254740992.0
_LOW40 = (1 << 40) - 1


@njit(nogil=True, cache=True)
def _scaled(v: float, p10: int) -> int | np.int64:  # pragma: no cover - jit
    """round_half_even(v·p10) for finite 0 ≤ v with v·p10 < 2^62 and p10 < 2^30, exactly."""
    if v == 0.0:
        return 0
    mant, ex = math.frexp(v)
    m = np.int64(mant * _TWO53)  # v = m·2^(ex − 53), m < 2^53 exactly
    s = 53 - ex  # the right shift; v·p10 < 2^62 with v ≥ 2^(ex−1) keeps s ≥ 1 in practice
    # P = m·p10 = h·2^40 + l, both limbs non-negative int64 (P < 2^83)
    a = (m & 0xFFFFFFFF) * p10  # < 2^62
    b = (m >> 32) * p10  # < 2^51
    t = a + ((b & 0xFF) << 32)  # < 2^62 + 2^40
    low = t & _LOW40
    high = (b >> 8) + (t >> 40)  # < 2^44
    if s <= 0:
        # v ≥ 2^52: an integer, P·2^−s; only reachable for p10 < 2^10 within the limit
        return ((high << 40) + low) << (-s)
    if s >= 84:
        return 0  # P < 2^83 ≤ half a unit: rounds to zero
    if s < 40:
        n = (high << (40 - s)) + (low >> s)
        rnd = (low >> (s - 1)) & 1
        sticky = (low & ((np.int64(1) << (s - 1)) - 1)) != 0
    else:
        n = high >> (s - 40)
        k = s - 1  # the rounding bit
        if k < 40:
            rnd = (low >> k) & 1
            sticky = (low & ((np.int64(1) << k) - 1)) != 0
        else:
            rnd = (high >> (k - 40)) & 1
            sticky = low != 0 or (high & ((np.int64(1) << (k - 40)) - 1)) != 0
    if rnd == 1 and (sticky or (n & 1) == 1):
        n += 1
    return n


@njit(nogil=True, cache=True)
def _scale_all(
    values: np.ndarray, p10: int, units: np.ndarray, negative: np.ndarray
) -> int:  # pragma: no cover - jit
    """Units of the last decimal and signs of every value; returns the flat index of the
    first value that is not finite or too large (−1 if none)."""
    flat = values.reshape(-1)
    for i in range(flat.size):
        v = flat[i]
        if not math.isfinite(v) or abs(v) * p10 >= LIMIT:
            return i
        negative[i] = v < 0.0 or (v == 0.0 and math.copysign(1.0, v) < 0.0)
        units[i] = _scaled(abs(v), p10)
    return -1


@njit(nogil=True, cache=True)
def _digits(n: int) -> int:  # pragma: no cover - jit
    count = 1
    while n >= 10:
        n //= 10
        count += 1
    return count


@njit(nogil=True, cache=True, inline="always")
def _put_digits(out: np.ndarray, pos: int, n: int, width: int) -> int:  # pragma: no cover - jit
    """The ``width`` lowest decimal digits of ``n`` ≥ 0 (zero-padded) at ``out[pos:]``;
    returns the position after them."""
    for j in range(width - 1, -1, -1):
        out[pos + j] = 48 + n % 10
        n //= 10
    return pos + width


@njit(nogil=True, cache=True)
def _render(
    units: np.ndarray, negative: np.ndarray, cols: int, decimals: int, p10: int, out: np.ndarray
) -> int:  # pragma: no cover - jit
    """Write the rows of ``cols`` numbers (single spaces between, newlines between rows, none
    after the last) into ``out`` (uint8); returns the bytes written. With ``out`` empty, only
    counts them."""
    size = units.size
    pos = 0
    write = out.size > 0
    for i in range(size):
        n = units[i]
        whole = n // p10
        frac = n - whole * p10
        width = _digits(whole)
        if write:
            if negative[i]:
                out[pos] = 45  # '-'
                pos += 1
            pos = _put_digits(out, pos, whole, width)
            out[pos] = 46  # '.'
            pos = _put_digits(out, pos + 1, frac, decimals)
            if i + 1 < size:
                out[pos] = 32 if (i + 1) % cols else 10
                pos += 1
        else:
            pos += negative[i] + width + 1 + decimals + (1 if i + 1 < size else 0)
    return pos


class Fixed(NamedTuple):
    """Numbers as printed with ``decimals`` decimals: the units of the last decimal of each
    (int64, flat), whether each is negative (its sign printed), and the array's shape."""

    units: np.ndarray
    negative: np.ndarray
    decimals: int
    shape: tuple[int, ...]


def fixed(values: np.ndarray, decimals: int = 9) -> Fixed:
    """The (rows, columns) array ``values`` as printed with ``decimals`` (1..9) decimals,
    exactly (module docstring). Raises ValueError naming a value that is not finite or
    ≥ 2^62/10^decimals in magnitude."""
    if not 1 <= decimals <= 9:
        raise ValueError(f"decimals must be 1..9, got {decimals}")
    values = np.ascontiguousarray(values, dtype=np.float64)
    if values.ndim != 2:
        raise ValueError(f"rows of numbers must form a 2-D array, got shape {values.shape}")
    p10 = 10**decimals
    units = np.empty(values.size, dtype=np.int64)
    negative = np.empty(values.size, dtype=np.bool_)
    bad = _scale_all(values, p10, units, negative)
    if bad >= 0:
        row, col = divmod(int(bad), values.shape[1])
        raise ValueError(
            f"row {row}, column {col}: {values.reshape(-1)[bad]!r} cannot be written with {decimals} "
            f"decimals (finite and below {LIMIT / p10:.3g} in magnitude)"
        )
    return Fixed(units, negative, decimals, values.shape)


def rows_bytes(values: np.ndarray | Fixed, decimals: int = 9) -> bytes:
    """The rows of ``values`` (n, c) (or of their :func:`fixed` form) as ASCII: each number as
    ``format(v, f".{decimals}f")`` prints it, single spaces between the numbers of a row, rows
    joined by newlines (none after the last)."""
    f = values if isinstance(values, Fixed) else fixed(values, decimals)
    cols = max(int(f.shape[1]), 1)
    p10 = 10**f.decimals
    size = _render(f.units, f.negative, cols, f.decimals, p10, np.empty(0, dtype=np.uint8))
    out = np.empty(size, dtype=np.uint8)
    _render(f.units, f.negative, cols, f.decimals, p10, out)
    return out.tobytes()


def rows_text(values: np.ndarray | Fixed, decimals: int = 9) -> str:
    """:func:`rows_bytes` as a string."""
    return rows_bytes(values, decimals).decode("ascii")


def printed(values: np.ndarray | Fixed, decimals: int = 9) -> np.ndarray:
    """The numbers :func:`rows_text` prints for ``values`` (or their :func:`fixed` form), as
    read back (``float`` of each printed number, signed zeros kept), shape of ``values``."""
    f = values if isinstance(values, Fixed) else fixed(values, decimals)
    p10 = 10**f.decimals
    out = f.units.astype(np.float64) / p10
    big = f.units >= 2**53  # N/10^d would round twice: read those few from their text
    if np.any(big):
        out[big] = [float(f"{n // p10}.{n % p10:0{f.decimals}d}") for n in f.units[big].tolist()]
    out[f.negative] = -out[f.negative]
    return out.reshape(f.shape)


# _parse and _fault stay one loop each over the bytes, above the complexity gate: split into
# helpers (a number's digits, its form), they ran 2.7× and 3.5× slower on a million lines of
# four numbers (0.133 against 0.049 s, 0.110 against 0.031 s, docs/performance.md)
@njit(nogil=True, cache=True)
def _parse(  # noqa: C901
    buf: np.ndarray, cols: int, decimals: int, p10: int, out: np.ndarray
) -> int:  # pragma: no cover - jit
    """Read rows of ``cols`` numbers written as :func:`_render` writes them ('-'? digits '.'
    1..``decimals`` digits, single spaces between, newlines between rows, none after the last)
    into ``out`` as :func:`printed` reads them back (N/10^d, N < 2^53); returns how many
    numbers were read, or −1 − the byte position where the text leaves that form or a number
    needs N ≥ 2^53 (the caller then reads the text as general text)."""
    n = buf.size
    cap = out.size
    most = (np.int64(1) << 53) // p10  # whole parts up to this keep N below 2^53 (checked below)
    pos = 0
    k = 0
    while pos < n:
        if k >= cap:
            return -1 - pos
        neg = buf[pos] == 45
        if neg:
            pos += 1
        start = pos
        whole = np.int64(0)
        while pos < n and 48 <= buf[pos] <= 57:
            whole = whole * 10 + (buf[pos] - 48)
            pos += 1
            if whole > most:
                return -1 - pos
        if pos == start or pos >= n or buf[pos] != 46:
            return -1 - pos
        pos += 1
        first = pos
        frac = np.int64(0)
        while pos < n and 48 <= buf[pos] <= 57 and pos - first < decimals:
            frac = frac * 10 + (buf[pos] - 48)
            pos += 1
        if pos == first:
            return -1 - pos
        for _ in range(decimals - (pos - first)):
            frac *= 10
        units = whole * p10 + frac
        if units >= np.int64(1) << 53:
            return -1 - pos
        # both exact in a double: one correctly rounded division, the nearest double to the text
        v = np.float64(units) / p10
        out[k] = -v if neg else v
        k += 1
        if pos == n:
            break
        if buf[pos] != (32 if k % cols else 10) or pos + 1 == n:
            return -1 - pos
        pos += 1
    if k % cols:
        return -1 - pos
    return k


def parse_rows(text: bytes | memoryview, cols: int, decimals: int = 9) -> np.ndarray | None:
    """The (rows, ``cols``) numbers of ``text`` when it is written as :func:`rows_bytes` writes
    (at most ``decimals`` decimals, no exponent, single spaces, one newline between rows), read
    as :func:`printed` reads them back: the double nearest to each printed decimal, as any
    correctly rounding reader (numpy's ``loadtxt``, ``float``) gives it (module docstring).
    None when the text leaves that form anywhere, or holds a number of 2^53 units or more (the
    caller reads it as general text and names what is wrong); a million lines of four numbers
    in ~0.08 s, where splitting them and ``loadtxt`` took 0.3 s."""
    if not 1 <= decimals <= 9 or cols < 1:
        raise ValueError(f"need 1..9 decimals and a column or more, got {decimals}, {cols}")
    buf = np.frombuffer(text, dtype=np.uint8)
    if buf.size == 0:
        return np.empty((0, cols))
    rows = int(np.count_nonzero(buf == 10)) + 1
    out = np.empty(rows * cols)
    if _parse(buf, cols, decimals, 10**decimals, out) != out.size:
        return None
    return out.reshape(rows, cols)


@njit(nogil=True, cache=True)
def _fault(buf: np.ndarray, cols: int, decimals: int) -> int:  # noqa: C901  # pragma: no cover - jit
    """−1 when ``buf`` is rows of ``cols`` numbers exactly as :func:`_render` writes them
    ('-'? ('0' | [1-9][0-9]*) '.' exactly ``decimals`` digits; single spaces between numbers,
    one LF between rows, none after the last); else the byte position where it leaves that
    form."""
    n = buf.size
    pos = 0
    k = 0
    while pos < n:
        if buf[pos] == 45:
            pos += 1
        start = pos
        while pos < n and 48 <= buf[pos] <= 57:
            pos += 1
        if pos == start or (buf[start] == 48 and pos - start > 1):
            return start if pos == start else start + 1
        if pos >= n or buf[pos] != 46:
            return pos
        pos += 1
        first = pos
        while pos < n and 48 <= buf[pos] <= 57 and pos - first < decimals:
            pos += 1
        if pos - first != decimals:
            return pos
        k += 1
        if pos == n:
            break
        if buf[pos] != (32 if k % cols else 10) or pos + 1 == n:
            return pos
        pos += 1
    if k % cols or k == 0:
        return pos
    return -1


def fault(text: bytes | memoryview, cols: int, decimals: int = 9) -> int:
    """−1 when ``text`` is byte for byte rows of ``cols`` numbers as :func:`rows_bytes`
    writes them with ``decimals`` decimals (what a controller reads is what export wrote);
    else the byte offset [bytes from the start of ``text``] of the first departure: an
    exponent, a '+', a leading zero, another count of decimals, two spaces, a CR, a blank
    line, a missing or extra number."""
    buf = np.frombuffer(text, dtype=np.uint8)
    if buf.size == 0:
        return -1
    return int(_fault(buf, cols, decimals))
