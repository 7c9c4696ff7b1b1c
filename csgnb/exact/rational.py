"""Exact rationals as text of any size: JSON reports, checkpoints and summaries.

Exact volumes of long runs are Fractions whose denominators have 10^4-10^5 digits. Python
refuses to convert an int of more than 4,300 digits to decimal text (``sys.set_int_max_str_digits``:
a denial-of-service guard), so a report written with ``f"{v.numerator}/{v.denominator}"`` fails at
the end of a long run. Here a value is written in decimal while both parts are short and in
hexadecimal (linear time, no limit) beyond that; :func:`parse_fraction` reads both.

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

__all__ = ["decimal_digits", "describe_fraction", "fraction_text", "parse_fraction"]

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
        return Fraction(part(num), part(den) if den else 1)
    except (ValueError, ZeroDivisionError) as exc:
        raise ValueError(f"{text[:40]!r} is not an exact value written as 'n/d': {exc}") from None


def describe_fraction(v: Fraction, limit: int = 48) -> str:
    """``"exact: n/d"`` when short, else the digit counts (never converts a huge part to decimal)."""
    v = Fraction(v)
    if decimal_digits(v.numerator) + decimal_digits(v.denominator) < limit:
        return f"exact: {fraction_text(v)}"
    return f"exact: a Fraction of {decimal_digits(v.numerator)}/{decimal_digits(v.denominator)} digits"
