"""The repository's sample data: written as docs/identify.md says, and ``softcurve fit``
gives back the law they were computed with."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

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
