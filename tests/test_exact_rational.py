"""Exact rationals of any size (``csgnb.exact.rational``): GMP-backed sums, reductions and power-of-two rescaling
against Python's own ``fractions.Fraction`` arithmetic, value and normal form (a Fraction built without its gcd must
still be reduced, or equal values would compare unequal)."""

from fractions import Fraction

from hypothesis import given, settings
from hypothesis import strategies as st

from csgnb.exact import rational
from csgnb.exact.rational import (
    coprime_fraction,
    fraction_text,
    parse_fraction,
    reduced_fraction,
    sum_fraction_pairs,
    times_power_of_two,
)

ints = st.one_of(st.integers(-(2**70), 2**70), st.integers(-(2**3000), 2**3000))
positive = st.one_of(st.integers(1, 2**70), st.integers(1, 2**3000))


def same(a: Fraction, b: Fraction) -> bool:
    """Equal in value and in normal form (numerator, denominator > 0, coprime) and hash."""
    return (a.numerator, a.denominator) == (b.numerator, b.denominator) and hash(a) == hash(b) and a == b


@given(ints, ints.filter(bool))
def test_reduced_fraction_is_fraction(n, d):
    assert same(reduced_fraction(n, d), Fraction(n, d))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(ints, positive), max_size=40), st.sampled_from([1, 2, 3, 6, 2**64, 3**40]))
def test_pairwise_sums_are_reduced_sums(terms, common):
    """Terms with shared factors (``common``), a single term (returned reduced), none; added over the running common
    denominator, and with the pairwise fallback taking over after the first terms."""
    terms = [(n, d * common) for n, d in terms]
    expected = sum((Fraction(n, d) for n, d in terms), Fraction(0))
    num, den = sum_fraction_pairs(terms)
    assert same(coprime_fraction(num, den), expected)
    # the pairwise rest, from wherever the running common denominator passes its bound (here: almost at once)
    bound = rational.RUNNING_SUM_BITS
    try:
        rational.RUNNING_SUM_BITS = 8
        num, den = sum_fraction_pairs(terms)
    finally:
        rational.RUNNING_SUM_BITS = bound
    assert same(coprime_fraction(num, den), expected)


@given(ints, positive, st.integers(-400, 400))
def test_times_power_of_two(n, d, k):
    v = Fraction(n, d)
    assert same(times_power_of_two(v, k), v * Fraction(2) ** k)


def test_huge_values_round_trip_as_text():
    v = sum((Fraction(1, 3**k + 2**k) for k in range(1, 400)), Fraction(0))  # a denominator of ~10^5 bits
    assert v.denominator.bit_length() > 50_000
    assert same(parse_fraction(fraction_text(v)), v)
