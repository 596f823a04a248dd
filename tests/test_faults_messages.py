"""Fault injection (issue 29): the messages a user meets, in the library's own words,
and the step budget of every integrator.

Each case asserts the status or exception, the key words of the one-line message and
physically sane numbers; budgets are asserted on counts, never on time.
"""

from __future__ import annotations

import contextlib
import dataclasses

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.cli import main
from softcurve.simulation._settings import SimulationSettings
from softcurve.simulation.solvers import casadi_only
from softcurve.symbolic.contact import signed_distance

Q0 = np.array([0.064, 0.0, 0.0])
STIFF_LOAD = [0.0, 1e4, 0.0]
"""Issue 29's stiff case on the paper robot: a bending moment that throws the segment out
of the model's domain within the first millisecond."""


# -- item 6: one step budget, max_steps per output interval, for every method ----------


@pytest.mark.parametrize("method", ["cvodes", "adams", "bdf", "rk45", "casadi"])
def test_the_step_budget_is_max_steps_per_output_interval(paper_model, method, monkeypatch):
    """A budget of 10 steps cannot cover the first millisecond under the stiff load: every
    method stops there, after at most max_steps (+1) steps, naming max_steps. Before,
    RK45 counted max_steps times the number of outputs in all (1001 steps here)."""
    casadi = method == "casadi"
    method = "cvodes" if casadi else method
    max_steps = 10
    # CVODES inside CasADi's integrator, without the C driver: its own mxstep
    with casadi_only() if casadi else contextlib.nullcontext():
        run = sc.simulate(
            paper_model, Q0, np.zeros(3), t_final=0.1, tau=STIFF_LOAD, method=method,
            max_steps=max_steps,
        )  # fmt: skip
    assert run.status is Status.INTEGRATION_FAILED, run.message
    assert "max_steps" in run.message and run.t.size == 1
    if not casadi:  # CasADi reports no counts of a failed call
        assert 1 <= run.stats["steps"] <= max_steps + 1


def test_the_batch_step_budget_is_per_output_interval_too(paper_model):
    """simulate_batch (CVODES's C driver): the stiff member stops at its first output
    interval naming max_steps, the other runs on (a guard: it held before)."""
    batch = sc.simulate_batch(
        paper_model, np.array([Q0, Q0]), np.zeros(3), tau=np.array([STIFF_LOAD, np.zeros(3)]),
        t_final=0.01, max_steps=10, threads=1,
    )  # fmt: skip
    assert batch.member_status[0] is Status.INTEGRATION_FAILED
    assert "max_steps" in batch.member_message[0] and batch.reached[0] == 1
    assert batch.member_status[1] is Status.SUCCESS


def test_rk45_under_a_stiff_load_stops_at_the_first_output_outside_the_domain(paper_model):
    """Issue 29's case (paper robot, tau = [0, 1e4, 0]) with RK45: the first output is
    outside the domain (l = 3.6 m); RK45 stops there, as CVODES's driver does, after the
    tens of steps that interval needs. Before, it went on outside the domain, where the
    motion needs steps shorter than 1e-8 s, until the budget of all outputs was spent
    (here 3 x 2000 steps; 100 x 50 000 by default for 0.1 s: it never returned)."""
    run = sc.simulate(
        paper_model, Q0, np.zeros(3), t_final=0.003, tau=STIFF_LOAD, method="rk45",
        max_steps=2000,
    )  # fmt: skip
    assert run.status is Status.LEFT_DOMAIN, run.message
    assert "l of segment 1" in run.message and run.t.size == 1
    assert run.stats["steps"] < 1000


# -- item 4: obstacles' directions of any finite nonzero length --------------------------


@pytest.mark.parametrize(
    ("normal", "unit"),
    [
        ([1e200, 1e200, 0.0], [2**-0.5, 2**-0.5, 0.0]),  # before: stored as [0, 0, 0]
        ([1e-200, 0.0, 0.0], [1.0, 0.0, 0.0]),  # before: refused as zero
        ([0.0, -5e-324, 0.0], [0.0, -1.0, 0.0]),
        ([1.7e308, -1.7e308, 1.7e308], [3**-0.5, -(3**-0.5), 3**-0.5]),
    ],
)
def test_a_plane_normal_of_any_finite_nonzero_length_is_its_direction(normal, unit):
    plane = sc.Plane(point=[0.0, 0.0, 0.0], normal=normal)
    np.testing.assert_allclose(plane.normal, unit, rtol=1e-15, atol=0)
    assert np.linalg.norm(plane.normal) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize(
    ("normal", "words"),
    [([0.0, 0.0, 0.0], "[0.0, 0.0, 0.0]"), ([np.inf, 0, 0], "finite")],
)
def test_only_a_zero_or_non_finite_normal_is_refused_with_its_value(normal, words):
    """A guard of what stays refused (as before)."""
    with pytest.raises(sc.ParameterError, match="Plane.normal") as error:
        sc.Plane(point=[0.0, 0.0, 0.0], normal=normal)
    assert words in str(error.value)


def test_a_short_capsule_axis_is_kept_and_its_distance_is_exact():
    """b - a = [1e-170, 1e-170, 0]: distinct ends, whose squared distance underflows.
    Before, it was refused with "got a = b = [0.0, 0.0, 0.0]", false of b."""
    capsule = sc.Capsule(a=[0.0, 0.0, 0.0], b=[1e-170, 1e-170, 0.0], radius=0.1)
    np.testing.assert_allclose(capsule.axis, [2**-0.5, 2**-0.5, 0.0], rtol=1e-15)
    assert capsule.length == pytest.approx(2**0.5 * 1e-170, rel=1e-15)
    distance = float(ca.evalf(signed_distance(capsule, ca.DM([0.0, 0.0, 1.0]))))
    assert distance == pytest.approx(0.9, rel=1e-12)


def test_the_capsule_message_says_a_equals_b_only_when_it_does():
    with pytest.raises(sc.ParameterError, match=r"got a = b = \[1.0, 2.0, 3.0\]"):
        sc.Capsule(a=[1.0, 2.0, 3.0], b=[1.0, 2.0, 3.0], radius=0.1)
    with pytest.raises(sc.ParameterError, match="Capsule axis b - a") as error:
        sc.Capsule(a=[1.7e308, 0.0, 0.0], b=[-1.7e308, 0.0, 0.0], radius=0.1)
    assert "a = b" not in str(error.value) and "must be finite" in str(error.value)


# -- item 9: a Python int beyond the float range given to a float field -----------------

HUGE = 10**400


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: dataclasses.replace(sc.presets.ifac2020().segments[0], mass=HUGE), "mass"),
        (lambda: sc.Sphere([0.0, 0.0, 0.0], -HUGE), "Sphere.radius"),
        (lambda: sc.Plane([HUGE, 0.0, 0.0], [0.0, 0.0, 1.0]), "Plane.point"),
        (lambda: sc.ContactLaw(stiffness=HUGE), "ContactLaw.stiffness"),
        (lambda: SimulationSettings(t_final=HUGE), "t_final"),
    ],
)
def test_an_int_beyond_the_float_range_is_refused_naming_the_field(build, field):
    """Before: OverflowError "int too large to convert to float"."""
    with pytest.raises(sc.ParameterError, match=rf"^{field} must be finite") as error:
        build()
    assert "1.8e+308" in str(error.value)


def test_a_huge_int_in_tau_is_refused_naming_tau(paper_model):
    with pytest.raises(sc.ParameterError, match="^tau must be finite"):
        sc.simulate(paper_model, Q0, np.zeros(3), t_final=0.01, tau=[HUGE, 0.0, 0.0])


# -- item 9: Gymnasium actions of the wrong shape or dtype --------------------------------


@pytest.fixture(scope="module")
def reach():
    """A single and a vector Reach environment (the paper robot's compiled stepper)."""
    pytest.importorskip("gymnasium")
    from softcurve import envs

    single, vector = envs.Reach(max_episode_steps=3), envs.ReachVector(2, max_episode_steps=3)
    single.reset(seed=0)
    vector.reset(seed=0)
    return single, vector


@pytest.mark.parametrize(
    ("action", "given"),
    [
        (0.5, "got shape ()"),  # before: IndexError "too many indices"
        ([0.5, 0.5], "got shape (2,)"),
        ([[0.5, 0.5, 0.5]], "got shape (1, 3)"),
        (["a", "b", "c"], "got dtype <U1"),
        ([0.5, None, 0.5], "got dtype object"),
        ([0.5, np.nan, 0.5], "non-finite"),
    ],
)
def test_a_wrong_single_action_names_the_action_space(reach, action, given):
    single, _ = reach
    with pytest.raises(
        sc.ParameterError, match=r"^action must be real numbers of shape \(3,\)"
    ) as error:
        single.step(action)
    assert given in str(error.value) and "[-1, 1]" in str(error.value)


@pytest.mark.parametrize(
    ("actions", "given"),
    [
        (np.zeros(6), "got shape (6,)"),  # before: reshaped silently
        (np.zeros(3), "got shape (3,)"),  # before: NumPy's reshape error
        (np.zeros((3, 3)), "got shape (3, 3)"),
        ([[0.1, 0.2, 0.3], [0.1, 0.2]], "got [["),  # ragged
    ],
)
def test_wrong_vector_actions_name_the_batched_action_space(reach, actions, given):
    _, vector = reach
    with pytest.raises(sc.ParameterError, match=r"^actions .* shape \(2, 3\)") as error:
        vector.step(actions)
    assert given in str(error.value)


def test_integer_actions_of_the_right_shape_are_accepted(reach):
    single, vector = reach
    assert np.isfinite(single.step(np.array([1, 0, -1]))[0]).all()
    assert np.isfinite(vector.step(np.array([[1, 0, -1], [0, 0, 0]]))[0]).all()


# -- item 9: the tanh fit of clean data, in any units -----------------------------------

GENTLE = sc.TanhStiffness(2230.0, 1115.0, -0.03)
"""A law that bends little over strains in [-1, 1] (|a3| x <= 0.03): before, its clean
fit ran out of SciPy's evaluations (2400) with SciPy's words."""


def _fit_cli(tmp_path, capsys, law, strain):
    path = tmp_path / "data.csv"
    np.savetxt(path, np.c_[strain, law.force(strain)], delimiter=",", header="x,f", comments="")
    code = main(["fit", str(path), "--strain", "x", "--force", "f"])
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err


def test_a_clean_tanh_fit_of_a_gently_bending_law_succeeds(tmp_path, capsys):
    strain = np.linspace(-1.0, 1.0, 60)
    report = sc.fit_stiffness(strain, GENTLE.force(strain))
    assert report.success, report.message
    np.testing.assert_allclose(report.values, [2230.0, 1115.0, 0.03], rtol=1e-6)
    code, out, _ = _fit_cli(tmp_path, capsys, GENTLE, strain)
    assert code == 0 and "status: success" in out


@pytest.mark.parametrize(
    ("strain_unit", "force_unit"), [(1.0, 1e-6), (1.0, 1e6), (1e150, 1e150), (1e-150, 1.0)]
)
def test_the_tanh_fit_is_the_same_in_any_units(strain_unit, force_unit):
    """The fit runs in units of the data's largest strain and force. Before, SciPy's
    absolute gradient tolerance made it depend on them: the paper's law with forces in
    micronewtons came back "success" with a2 off by 35 %, scaled by 1e150 "not
    identifiable" with overflows on the way."""
    paper = sc.TanhStiffness(2.23e3, 1.74e3, -4.55e2)
    strain = np.linspace(-4e-3, 8e-3, 80)
    report = sc.fit_stiffness(strain * strain_unit, paper.force(strain) * force_unit)
    assert report.success, report.message
    stiffness = force_unit / strain_unit
    expected = [paper.a1 * stiffness, paper.a2 * stiffness, abs(paper.a3) / strain_unit]
    np.testing.assert_allclose(report.values, expected, rtol=1e-6)


def test_data_whose_stiffness_has_no_float_is_refused_naming_their_range():
    strain = np.linspace(-1.0, 1.0, 20) * 1e200
    with pytest.raises(sc.ParameterError, match="the data's range") as error:
        sc.fit_stiffness(strain, 1e-200 * np.linspace(-1.0, 1.0, 20))
    assert "1e+200" in str(error.value) and "other units" in str(error.value)


def test_a_tanh_fit_the_data_cannot_settle_says_so_in_the_librarys_words(tmp_path, capsys):
    """The bend at |a3| = 300 over strains 0..1 sampled every 0.017: only the first point
    sees it, and a2, a3 are determined only together. Exit 1 with what to try, never
    SciPy's words."""
    law = sc.TanhStiffness(2230.0, 1115.0, -300.0)
    code, out, err = _fit_cli(tmp_path, capsys, law, np.linspace(0.0, 1.0, 60))
    assert code == 1
    assert "maximum number of function evaluations" not in out + err
    assert "a2 and a3 only together" in err and "--law linear" in err
