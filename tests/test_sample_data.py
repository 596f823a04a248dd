"""The repository's sample data: written as docs/identify.md says, and ``softcurve fit``
gives back the law they were computed with."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.cli import main
from softcurve.cli.fit import SAMPLE

ROOT = Path(__file__).resolve().parents[1]


def test_the_documented_command_writes_the_sample(tmp_path, monkeypatch):
    text = (ROOT / "docs" / "identify.md").read_text(encoding="utf-8")
    code = re.search(r"^python - <<'END'\n(.*?)^END$", text, re.S | re.M)
    assert code is not None and SAMPLE in code.group(1)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "examples").mkdir()
    exec(compile(code.group(1), "docs/identify.md", "exec"), {"__name__": "sample"})
    written, kept = (np.loadtxt(p, delimiter=",", skiprows=1) for p in (SAMPLE, ROOT / SAMPLE))
    assert written.shape == kept.shape == (25, 2)
    # the same up to the last of the nine digits (another platform's rounding)
    np.testing.assert_allclose(written, kept, rtol=1e-8, atol=1e-12)
    assert (ROOT / SAMPLE).read_text().splitlines()[0] == "angle,moment"


def test_fit_on_the_sample_gives_back_the_presets_bending_law(tmp_path, capsys):
    figure = tmp_path / "fit.png"
    argv = ["fit", str(ROOT / SAMPLE), "--strain", "angle", "--force", "moment"]
    assert main([*argv, "--figure", str(figure)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("status: success") and figure.stat().st_size > 0
    law = sc.presets.ifac2020().segments[0].bending_stiffness
    fitted = re.search(r"TanhStiffness\(a1=(\S+), a2=(\S+), a3=(\S+)\)", out)
    assert fitted is not None, out
    a1, a2, a3 = map(float, fitted.groups())
    # noiseless data: the law to the six digits printed (a3's sign does not matter)
    np.testing.assert_allclose([a1, a2, abs(a3)], [law.a1, law.a2, abs(law.a3)], rtol=1e-5)


def test_the_fit_report_and_figure_give_the_units_of_the_strains_kind(capsys):
    """``--mode bending``: the strain in rad, the moment in N m, the law's parameters in
    N m/rad and 1/rad, in the table and on the figure's axes (before: no unit anywhere);
    without ``--mode`` each unit is written as either."""
    import matplotlib.pyplot as plt

    from softcurve.identification.experiments import load_csv

    argv = ["fit", str(ROOT / SAMPLE), "--strain", "angle", "--force", "moment"]
    assert main([*argv, "--mode", "bending"]) == 0
    out = capsys.readouterr().out
    for row in ("a1 [N m/rad]", "a2 [N m/rad]", "a3 [1/rad]", "RMS "):
        assert row in out, out
    assert "residual force: RMS" in out and out.count(" N m,") == 1, out
    assert main([*argv, "--law", "linear"]) == 0
    assert "k0 [N/m or N m/rad]" in capsys.readouterr().out
    data = load_csv(ROOT / SAMPLE, signals=["angle", "moment"], time=None, sample_rate=1.0)
    report = sc.fit_stiffness(
        data.signals["angle"], data.signals["moment"], "linear", label="angle", mode="bending"
    )
    figure = report.plot()
    top, bottom = figure.axes
    assert top.get_ylabel() == "force [N m]" and bottom.get_xlabel() == "angle [rad]"
    assert bottom.get_ylabel() == "model - measured [N m]"
    assert report.parameter_units == ("N m/rad",)
    plt.close(figure)
    with pytest.raises(sc.ParameterError, match="mode must be 'elongation', 'bending'"):
        sc.fit_stiffness(data.signals["angle"], data.signals["moment"], "linear", mode="twist")
