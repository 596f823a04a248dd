"""The headline of the real-data goals (docs/validation.md, issue 16): b42 fitted with its
initial creep state identified.

Needs ../shared/data/caasenbrood2021 relative to the repository, or the directory in
$SOFTCURVE_DATA; skipped with a message otherwise.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from softcurve.base.status import Status

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "examples" / "validate_joint.py"

pytestmark = pytest.mark.data


def _script():
    spec = importlib.util.spec_from_file_location("validate_joint", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_b42_with_identified_initial_creep_state():
    script = _script()
    directory = script.vc.data_directory()
    if directory is None:
        pytest.skip(
            "real data absent: put caasenbrood2021 under ../shared/data (relative to the "
            "repository) or set SOFTCURVE_DATA"
        )
    experiments = script.vc.load_oscillations(directory, 2e-3)
    model = script.sc.Model(script.vc.data_robot("tanh"), quadrature_nodes=6)
    # Start near the optimum printed by `python examples/validate_joint.py` (tanh, b42,
    # creep free), so that a small budget suffices; the fit itself moves the estimate.
    start = {
        "segments[0].bending_stiffness.k_zero": 0.0045,
        "segments[0].bending_stiffness.k_inf": 0.0060,
        "segments[0].bending_stiffness.rate": 15.0,
    }
    fit = script.single_fit(
        model, experiments, "b42", "tanh", ("lam",), max_evaluations=25, start=start
    )
    assert fit["status"] in (Status.SUCCESS, Status.EVALUATION_LIMIT), fit["message"]
    # goal 0.20 deg (reached: 0.205 at 2 ms, 0.14 with the angle and IMU zero free);
    # assumed relaxed (lambda(0) = 0) the same model fits 0.31 deg
    assert fit["rms"]["b42"] < 0.25
    lam = fit["values"][fit["names"].index("x0.lam[1][b42]")]
    error = fit["errors"][fit["names"].index("x0.lam[1][b42]")]
    assert np.isfinite(error) and lam > 0  # held bent before release: a pre-stress
