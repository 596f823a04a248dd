"""The texts the commands print: rates to significant digits, honest units."""

from __future__ import annotations

import numpy as np
import pytest

from softcurve.cli import RATE_DIGITS, main, rate_text


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


def test_equilibria_labels_the_eigenvalues_of_the_scaled_hessian(capsys):
    """The column is the smallest eigenvalue of ``S K S`` [J] (the Hessian in the
    dimensionless coordinates), says so, and prints what ``equilibria`` computed."""
    import softcurve as sc
    from softcurve.analysis.equilibrium_results import EIGENVALUE_HEADING

    assert main(["equilibria", "--starts", "2"]) == 0
    printed = capsys.readouterr().out
    lines = printed.splitlines()
    header = next(i for i, line in enumerate(lines) if line.lstrip().startswith("#"))
    assert lines[header].endswith(EIGENVALUE_HEADING) and "SKS" in EIGENVALUE_HEADING
    assert "min eig [J]" not in lines[header]
    legend = " ".join(printed.split(f"\n  {EIGENVALUE_HEADING}: ")[1].split())
    assert legend.startswith("the smallest eigenvalue of S K S")
    assert "dimensionless coordinates (l/l0, kx l0, ky l0)" in legend
    table = sc.equilibria(sc.Model(sc.presets.ifac2020(), compile=False), starts=2, seed=0)
    assert float(lines[header + 1].split()[-1]) == pytest.approx(table[0].eigenvalues[0], rel=1e-3)
