"""Exact rationals as text of any size: JSON reports, checkpoints and summaries.

Exact volumes of long runs are Fractions whose denominators have 10^4-10^5 digits. Python
refuses to convert an int of more than 4,300 digits to decimal text (``sys.set_int_max_str_digits``:
a denial-of-service guard), so a report written with ``f"{v.numerator}/{v.denominator}"`` fails at
the end of a long run. Here a value is written in decimal while both parts are short and in
hexadecimal (linear time, no limit) beyond that; :func:`parse_fraction` reads both.

Such values are also slow to *make*: CPython's gcd and long division are quadratic in the digits,
and a Fraction reduces every result by a gcd. The exact volume of a 256-bit part carved by float
meshes has a denominator of millions of bits (every vertex its own 3x3 determinant of normals):
summed with Python ints, minutes to hours. :func:`sum_fraction_pairs` and :func:`reduced_fraction`
do their arithmetic in GMP (gmpy2: subquadratic gcd, division and products) and hand back plain
Python ints in a Fraction built without a second gcd (:func:`coprime_fraction`);
:func:`times_power_of_two` rescales (grid units to model units) by shifts alone.

>>> fraction_text(Fraction(-7, 3))
'-7/3'
>>> parse_fraction(fraction_text(Fraction(1, 3 ** 20000))) == Fraction(1, 3 ** 20000)
True
>>> fraction_text(Fraction(1, 3 ** 20000))[:6]
'0x1/0x'
"""

from __future__ import annotations

import math
from fractions import Fraction

import gmpy2

__all__ = ["coprime_fraction", "decimal_digits", "describe_fraction", "fraction_text", "parse_fraction",
           "reduced_fraction", "sum_fraction_pairs", "times_power_of_two"]

_DECIMAL_DIGITS = 1000
"""Parts with more decimal digits than this are written in hexadecimal."""

_LOG10_2 = math.log10(2)


def decimal_digits(n: int) -> int:
    """The number of decimal digits of ``|n|`` (exact, without converting ``n`` to decimal text)."""
    n = abs(n)
    if n == 0:
        return 1
    d = int(n.bit_length() * _LOG10_2)  # 10**d <= 2**(bits - 1) * 2 ... within one of the true count
    return d + 1 if n >= 10**d else d


def fraction_text(v: Fraction) -> str:
    """``v`` as ``"n/d"`` (decimal, or ``0x…/0x…`` for long parts); an integer as ``"n"``."""
    v = Fraction(v)
    n, d = v.numerator, v.denominator
    if max(n.bit_length(), d.bit_length()) * _LOG10_2 < _DECIMAL_DIGITS:
        return str(n) if d == 1 else f"{n}/{d}"
    return f"{'-' if n < 0 else ''}{hex(abs(n))}/{hex(d)}"


def parse_fraction(text: str) -> Fraction:
    """The Fraction written by :func:`fraction_text` (decimal or ``0x`` parts)."""
    if not isinstance(text, str):
        raise TypeError(f"an exact value is a string such as '7/3', got {type(text).__name__}")

    def part(s: str) -> int:
        s = s.strip()
        neg = s.startswith("-")
        body = s[1:] if neg else s
        value = int(body, 16) if body.lower().startswith("0x") else int(body)
        return -value if neg else value

    num, _, den = text.partition("/")
    try:
        return reduced_fraction(part(num), part(den) if den else 1)
    except (ValueError, ZeroDivisionError) as exc:
        raise ValueError(f"{text[:40]!r} is not an exact value written as 'n/d': {exc}") from None


def describe_fraction(v: Fraction, limit: int = 48) -> str:
    """``"exact: n/d"`` when short, else the digit counts (never converts a huge part to decimal)."""
    v = Fraction(v)
    if decimal_digits(v.numerator) + decimal_digits(v.denominator) < limit:
        return f"exact: {fraction_text(v)}"
    return f"exact: a Fraction of {decimal_digits(v.numerator)}/{decimal_digits(v.denominator)} digits"


def coprime_fraction(num: int, den: int) -> Fraction:
    """``Fraction(num, den)`` for ``den > 0`` and ``gcd(num, den) == 1``, without the gcd the constructor would compute
    again (quadratic in CPython). The caller vouches for both conditions.

    >>> coprime_fraction(-7, 3) == Fraction(-7, 3)
    True
    """
    from_coprime = getattr(Fraction, "_from_coprime_ints", None)  # Python >= 3.12
    if from_coprime is not None:
        return from_coprime(num, den)
    return Fraction(num, den, _normalize=False)


def reduced_fraction(num: int, den: int) -> Fraction:
    """``Fraction(num, den)``, reduced by GMP's gcd (the same value; fast for parts of millions of bits).

    >>> reduced_fraction(6, -4)
    Fraction(-3, 2)
    """
    if den == 0:
        raise ZeroDivisionError(f"Fraction({num}, 0)")
    n, d = gmpy2.mpz(num), gmpy2.mpz(den)
    g = gmpy2.gcd(n, d)
    if d < 0:
        g = -g
    return coprime_fraction(int(n // g), int(d // g))


#: :func:`sum_fraction_pairs` adds over a running common denominator while it stays below this many bits, pairwise
#: beyond it.
RUNNING_SUM_BITS = 1 << 14


def sum_fraction_pairs(fractions: list[tuple[int, int]]) -> tuple[int, int]:
    """The sum of fractions ``(numerator, denominator > 0)`` as a reduced ``(numerator, denominator)``, in GMP.

    Terms are added over a running common multiple of the denominators seen so far: where a term's denominator
    divides it already -- most do, since the denominators of a solid's volume terms share their factors (a relief
    milling move's ~1,000 terms, ~1,000 distinct ~100-bit denominators, have a common multiple of ~240 bits) -- a
    term costs one division and one product, no gcd. Once the common multiple passes :data:`RUNNING_SUM_BITS`
    (denominators that share little, where a running sum would cost O(n^2) digit operations), the rest are added
    pairwise, about O(n log n) products and gcds of growing size. The relief milling's volume sums took half the
    time of pairwise throughout (benchmarks/bench_milling.py).

    >>> sum_fraction_pairs([(1, 3), (1, 6), (1, 2), (3, 4)])
    (7, 4)
    """
    if not fractions:
        return 0, 1
    mpz, gcd, f_divmod = gmpy2.mpz, gmpy2.gcd, gmpy2.f_divmod
    num, den = mpz(0), mpz(1)
    for i, (a, b) in enumerate(fractions):
        q, r = f_divmod(den, b)
        if not r:  # b divides the common denominator
            num += a * q
            continue
        g = gcd(den, b)  # the new common denominator: lcm(den, b) = den · (b / g), and a / b = a · (den / g) / it
        m = b // g
        num, den = num * m + a * (den // g), den * m
        if den.bit_length() > RUNNING_SUM_BITS and i + 1 < len(fractions):
            return _pairwise_sum([(num, den)] + [(mpz(c), mpz(d)) for c, d in fractions[i + 1:]])
    g = gcd(num, den)
    return int(num // g), int(den // g)


def _pairwise_sum(level: list) -> tuple[int, int]:
    """The reduced sum of ``(numerator, denominator > 0)`` pairs of ``gmpy2.mpz``, added pairwise."""
    gcd = gmpy2.gcd
    while len(level) > 1:
        nxt = []
        for i in range(0, len(level) - 1, 2):
            (a, b), (c, d) = level[i], level[i + 1]
            # over lcm(b, d): the denominators stay the common multiple, not the product; the sum's own common
            # factor with it (rare, small) is taken out once at the end
            g = gcd(b, d)
            q = d // g
            nxt.append((a * q + c * (b // g), b * q))
        if len(level) % 2:
            nxt.append(level[-1])
        level = nxt
    num, den = level[0]
    g = gcd(num, den)
    return int(num // g), int(den // g)


def times_power_of_two(v: Fraction, k: int) -> Fraction:
    """``v * 2**k`` (k of either sign) by shifts: the powers of two cancel against the other part's, no gcd.

    >>> times_power_of_two(Fraction(3, 8), 5), times_power_of_two(Fraction(12, 5), -4)
    (Fraction(12, 1), Fraction(3, 20))
    """
    num, den = v.numerator, v.denominator
    if num == 0:
        return Fraction(0)
    if k >= 0:
        t = min(k, (den & -den).bit_length() - 1)  # the denominator's factors of two cancel first
        return coprime_fraction(num << (k - t), den >> t)
    t = min(-k, (num & -num).bit_length() - 1)
    return coprime_fraction(num >> t, den << (-k - t))
