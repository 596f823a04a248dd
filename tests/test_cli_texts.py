"""The texts the commands print: rates to significant digits, honest units."""

from __future__ import annotations

import numpy as np
import pytest

from softcurve.cli import RATE_DIGITS, rate_text


@pytest.mark.parametrize(
    "value, text",
    [
        (0.38, "0.38"),
        (0.004, "0.004"),
        (0.0012345, "0.00123"),
        (1.0, "1"),
        (12.34, "12.3"),
        (999.4, "999"),
        (123456.7, "123457"),
    ],
)
def test_rates_print_to_significant_digits(value, text):
    assert rate_text(value) == text


@pytest.mark.parametrize("value", [0.38, 0.0517, 3.14159, 271.8, 5e5 + 0.3])
def test_a_printed_rate_reads_back_to_its_last_digit(value):
    """Read back, the text is within half a unit of its last digit: the last significant
    one below ``10**RATE_DIGITS``, the units digit above; a positive rate never reads 0."""
    printed = float(rate_text(value))
    large = value >= 10**RATE_DIGITS
    last_digit = 1.0 if large else 10.0 ** (np.floor(np.log10(value)) + 1 - RATE_DIGITS)
    assert 0 < printed and abs(printed - value) <= 0.5 * last_digit
