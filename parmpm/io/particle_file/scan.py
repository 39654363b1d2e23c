"""The fast read of a CSV particle table: one compiled pass over the file's bytes that splits the
rows and converts the numbers, so a 10⁷-row file costs seconds and its arrays once (no Python
string per row). The number conversion is Eisel and Lemire's (the algorithm of ``fast_float``:
a 128-bit product with a table of powers of five), exact: it gives the double Python's
``float()`` gives (more than 19 significant digits: when the first 19 and the first 19 plus
one unit in the last round alike, as ``fast_float`` does). Whatever it cannot be sure of — a
subnormal, ``nan``, ``inf``, ``1_000``, any text that is not a plain decimal — it leaves to
``float()`` as a *hard* token; a byte the scan does not handle (non-ASCII, a quote, a control
character, a lone carriage return) sends the whole file to the precise reader
(:mod:`parmpm.io.particle_file.table`), so both readers accept the same files and give the same
numbers and errors.
"""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import kernel

OK, BAIL, FIELDS = 0, 1, 2
_M32 = np.uint64(0xFFFFFFFF)
_ONES = np.uint64(0xFFFFFFFFFFFFFFFF)
_S32, _S1, _S63, _S52 = np.uint64(32), np.uint64(1), np.uint64(63), np.uint64(52)
_ZERO = np.uint64(0)
_MASK_HI = np.uint64(0x1FF)  # the low 9 bits of the product's high word (64 - 52 - 3)
_Q_MIN, _Q_MAX = -342, 308


def _powers_of_five() -> np.ndarray:
    """128-bit approximations of 5^q, q = -342 .. 308, as (high, low) words (fast_float's table:
    truncated for q >= 0, rounded up for q < 0)."""
    out = np.zeros((_Q_MAX - _Q_MIN + 1, 2), np.uint64)
    for q in range(_Q_MIN, _Q_MAX + 1):
        if q >= 0:
            c = 5 ** q
            while c < 1 << 127:
                c <<= 1
            while c >= 1 << 128:
                c >>= 1
        else:
            p = 5 ** -q
            z = p.bit_length()
            c = (1 << (z + 127 if q >= -27 else 2 * z + 128)) // p + 1
            while c >= 1 << 128:
                c >>= 1
        out[q - _Q_MIN] = (c >> 64, c & ((1 << 64) - 1))
    return out


POW5 = _powers_of_five()


@kernel
def _mul(a, b):
    """The 128-bit product of two uint64, as (high, low)."""
    a0, a1, b0, b1 = a & _M32, a >> _S32, b & _M32, b >> _S32
    p0, p1, p2, p3 = a0 * b0, a0 * b1, a1 * b0, a1 * b1
    mid = (p0 >> _S32) + (p1 & _M32) + (p2 & _M32)
    return p3 + (p1 >> _S32) + (p2 >> _S32) + (mid >> _S32), (p0 & _M32) | (mid << _S32)


@kernel
def _to_bits(w, q, neg, pow5):
    """The bits of the double nearest ``w·10^q`` (w < 10^19, w > 0), or (False, 0) where the
    algorithm cannot be sure (then ``float()`` decides)."""
    if q < _Q_MIN or q > _Q_MAX:
        return False, _ZERO
    lz = 0
    while (w >> _S63) == _ZERO:
        w = w << _S1
        lz += 1
    k = q - _Q_MIN
    hi, lo = _mul(w, pow5[k, 0])
    if (hi & _MASK_HI) == _MASK_HI:
        hi2, _ = _mul(w, pow5[k, 1])
        lo = lo + hi2
        if hi2 > lo:
            hi = hi + _S1
    if lo == _ONES:
        return False, _ZERO
    upper = hi >> _S63
    shift = upper + np.uint64(9)
    mant = hi >> shift
    power2 = (((152170 + 65536) * q) >> 16) + 63 + np.int64(upper) - lz + 1023
    if power2 <= 0 or power2 >= 0x7FE:
        return False, _ZERO
    if lo <= _S1 and -4 <= q <= 23 and (mant & np.uint64(3)) == _S1:
        if (mant << shift) == hi:
            mant = mant & ~_S1
    mant = mant + (mant & _S1)
    mant = mant >> _S1
    if mant >= (np.uint64(2) << _S52):
        mant = np.uint64(1) << _S52
        power2 += 1
    mant = mant & ~(np.uint64(1) << _S52)
    bits = mant | (np.uint64(power2) << _S52)
    if neg:
        bits = bits | (_S1 << _S63)
    return True, bits


@kernel
def _number(buf, s, e, pow5):
    """A plain decimal ``[+-]digits[.digits][(e|E)[+-]digits]`` in ``buf[s:e]`` as (True, bits),
    else (False, 0)."""
    p, neg = s, False
    if p < e and (buf[p] == 43 or buf[p] == 45):
        neg = buf[p] == 45
        p += 1
    w, nd, exp10, digits, cut = _ZERO, 0, 0, 0, False  # cut: a non-zero digit past the 19th
    while p < e and 48 <= buf[p] <= 57:
        d = np.uint64(buf[p] - 48)
        if nd > 0 or d != _ZERO:
            if nd < 19:
                w = w * np.uint64(10) + d
                nd += 1
            else:
                exp10 += 1
                cut = cut or d != _ZERO
        digits += 1
        p += 1
    if p < e and buf[p] == 46:
        p += 1
        while p < e and 48 <= buf[p] <= 57:
            d = np.uint64(buf[p] - 48)
            if nd < 19:
                if nd > 0 or d != _ZERO:
                    w = w * np.uint64(10) + d
                    nd += 1
                exp10 -= 1
            else:
                cut = cut or d != _ZERO
            digits += 1
            p += 1
    if digits == 0:
        return False, _ZERO
    if p < e and (buf[p] == 101 or buf[p] == 69):
        p += 1
        sign = 1
        if p < e and (buf[p] == 43 or buf[p] == 45):
            sign = -1 if buf[p] == 45 else 1
            p += 1
        if p == e:
            return False, _ZERO
        ex = 0
        while p < e and 48 <= buf[p] <= 57:
            if ex < 100000:
                ex = ex * 10 + (buf[p] - 48)
            p += 1
        exp10 += sign * ex
    if p != e:
        return False, _ZERO
    if nd == 0:
        return True, (_S1 << _S63) if neg else _ZERO
    ok, bits = _to_bits(w, exp10, neg, pow5)
    if ok and cut:  # the value lies between w·10^q and (w+1)·10^q: exact if both round alike
        ok2, bits2 = _to_bits(w + _S1, exp10, neg, pow5)
        ok = ok2 and bits2 == bits
    return ok, bits


@kernel
def _grow(a, n):
    b = np.empty((2 * a.shape[0], a.shape[1]), a.dtype)
    b[:n] = a[:n]
    return b


@kernel
def _line_end(buf, i, n):
    """The end of the line from ``i`` (its ``\\n``, or n) and whether it holds a byte the scan
    does not handle (non-ASCII, a control character, a lone ``\\r``, a quote)."""
    bad = False
    while i < n and buf[i] != 10:
        c = buf[i]
        if c >= 127 or c == 34 or (c < 32 and c != 9 and not (c == 13 and i + 1 < n
                                                                     and buf[i + 1] == 10)):
            bad = True
        i += 1
    return i, bad


@kernel
def scan(buf, pos, line0, cap, comma, kinds, comps, dest, mat, pow5):
    """Rows of the table (at most ``cap``) from byte ``pos`` (line ``line0``): column ``c``'s numbers (as bits)
    into ``dest[kinds[c]][row, comps[c]]`` (``kinds[c] < 0``: the material column, its token's
    bounds into ``mat[row]``). Returns (status, rows, line, fields, hard, n_hard):
    ``hard[:n_hard]`` the tokens left to ``float()`` as (row, column, start, end); status
    FIELDS: ``line`` holds ``fields`` fields; BAIL: a byte the scan does not handle."""
    n, ncols = buf.shape[0], kinds.shape[0]
    hard = np.empty((64, 4), np.int64)
    nh, row, line, i = 0, 0, line0, pos
    while i < n:
        end, bad = _line_end(buf, i, n)
        if bad:
            return BAIL, row, line, 0, hard, nh
        stop = end - 1 if end > i and buf[end - 1] == 13 else end
        j = i
        while j < stop and (buf[j] == 32 or buf[j] == 9):
            j += 1
        if j < stop and buf[j] != 35:
            if row >= cap:
                return BAIL, row, line, 0, hard, nh
            k = 0
            while j <= stop:
                while j < stop and (buf[j] == 32 or buf[j] == 9 or (not comma and buf[j] == 13)):
                    j += 1
                if not comma and j == stop:
                    break
                s = j
                if comma:
                    while j < stop and buf[j] != 44:
                        j += 1
                else:
                    while j < stop and buf[j] != 32 and buf[j] != 9 and buf[j] != 13:
                        j += 1
                e = j
                while e > s and (buf[e - 1] == 32 or buf[e - 1] == 9):
                    e -= 1
                if k < ncols:
                    c = kinds[k]
                    if c < 0:
                        mat[row, 0], mat[row, 1] = s, e
                    else:
                        ok, b = _number(buf, s, e, pow5)
                        dest[c][row, comps[k]] = b
                        if not ok:
                            if nh == hard.shape[0]:
                                hard = _grow(hard, nh)
                            hard[nh, 0], hard[nh, 1], hard[nh, 2], hard[nh, 3] = row, k, s, e
                            nh += 1
                k += 1
                j += 1  # past the comma (or past the line's end: the loop stops)
            if k != ncols:
                return FIELDS, row, line, k, hard, nh
            row += 1
        line += 1
        i = end + 1
    return OK, row, line, 0, hard, nh


@kernel
def line_of(buf, pos, line0, want):
    """The line number of row ``want`` (from byte ``pos``, line ``line0``): for an error."""
    n, row, line, i = buf.shape[0], 0, line0, pos
    while i < n:
        end, _ = _line_end(buf, i, n)
        j = i
        while j < end and (buf[j] == 32 or buf[j] == 9 or buf[j] == 13):
            j += 1
        if j < end and buf[j] != 35:
            if row == want:
                return line
            row += 1
        line += 1
        i = end + 1
    return -1


@kernel
def gather(buf, bounds, width):
    """The tokens ``buf[s:e]`` of ``bounds`` as a (rows, width) zero-padded byte table."""
    out = np.zeros((bounds.shape[0], width), np.uint8)
    for r in range(bounds.shape[0]):
        for k in range(bounds[r, 1] - bounds[r, 0]):
            out[r, k] = buf[bounds[r, 0] + k]
    return out
