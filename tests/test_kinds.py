"""Every element kind through the same identities: the three chain algorithms against
each other, D symmetric positive definite, Ddot - 2C skew, forces as gradients of the
energies, the power balance, the kinetic energy against the pose's velocities, energy
conserved without dissipation, the compiled model against CasADi's virtual machine.

Robots: the paper's constant-curvature segments; constant-strain segments with all six
strains (one with creep); and a mixed chain of a constant-strain segment that bends and
twists, a rigid link, a constant-curvature segment and a gripper at the tip, on a moved
and turned base.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import softcurve as sc

from .conftest import assert_close, random_state


def six_strain_segment(creep=False, damping=True, **changes):
    """A soft silicone segment 10 cm long, 1 cm radius, all six strains (linear laws of
    E = 1 MPa, G = E/3, Cowper's circle coefficient 0.9)."""
    r, length, e, g, rho = 0.01, 0.1, 1e6, 1e6 / 3, 1070.0
    area, inertia = np.pi * r**2, np.pi * r**4 / 4
    fields = dict(
        rest_length=length,
        mass=rho * area * length,
        radius=r,
        strains=sc.STRAINS,
        bending_stiffness=sc.LinearStiffness(e * inertia),
        torsion_stiffness=sc.LinearStiffness(g * 2 * inertia),
        shear_stiffness=sc.LinearStiffness(0.9 * g * area),
        stretch_stiffness=sc.LinearStiffness(e * area),
        damping=np.array([1e-5, 1e-5, 1e-5, 1e-2, 1e-2, 1e-2]) if damping else None,
        creep=sc.Creep(np.full(6, 5.0), np.full(6, 0.5), np.full(6, 1e-3)) if creep else None,
    )
    fields.update(changes)
    return sc.StrainSegment(**fields)


def gripper(mass=0.02):
    return sc.RigidBody(
        mass=mass,
        tip_position=[0.005, 0.0, 0.03],
        centre_of_mass=[0.002, -0.001, 0.012],
        inertia=[[3e-6, 2e-7, 0.0], [2e-7, 4e-6, 1e-7], [0.0, 1e-7, 2e-6]],
        tip_rotation=_rotation([0.3, -0.2, 0.5]),
    )


def _rotation(w):
    w = np.asarray(w, dtype=float)
    angle = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def robots(damping=True):
    paper = sc.presets.ifac2020(damping=damping).with_segments(2)
    tanh = six_strain_segment(
        damping=damping,
        bending_stiffness=sc.TanhStiffness(1.2e-2, 0.5e-2, 30.0),
        creep=None,
    )
    twisting = sc.StrainSegment(
        rest_length=0.08,
        mass=0.02,
        radius=0.012,
        strains=("twist", "bend_y", "bend_x"),
        bending_stiffness=sc.LinearStiffness(8e-3),
        torsion_stiffness=sc.LinearStiffness(5e-3),
        rest_strain=[2.0, 0.0, 1.5, 0.0, 0.0, 1.0],
        damping=[1e-5, 1e-5, 1e-5] if damping else None,
    )
    link = sc.RigidBody(mass=0.01, tip_position=[0.0, 0.0, 0.02], inertia=[1e-6, 1e-6, 5e-7])
    mixed = sc.Robot(
        segments=(twisting, link, paper.segments[0], gripper()),
        base_rotation=_rotation([0.2, 0.4, -0.1]),
        base_position=[0.1, -0.2, 0.3],
    )
    return {
        "curvature": paper,
        "six strains": sc.Robot(segments=(six_strain_segment(damping=damping), tanh)),
        "creep": sc.Robot(segments=(six_strain_segment(damping=damping, creep=True),)),
        "mixed": mixed,
    }


KINDS = tuple(robots())


@pytest.fixture(scope="module", params=KINDS)
def model(request):
    return sc.Model(robots()[request.param], compile=False)


def _function(e, inputs, outputs):
    return ca.Function("f", [*inputs, e.p], outputs)


def random_inputs(rng, model):
    """A random state near rest of ``model`` with input forces of the size of its gravity
    and elastic forces: ``(q, qd, tau, lam)``."""
    q, qd = random_state(rng, model)
    scale = np.abs(model.gravity_force(q)) + np.abs(model.elastic_force(q)) + 1e-9
    tau = rng.normal(size=model.n) * scale
    lam = rng.normal(size=model.n_creep) * 1e-3
    return q, qd, tau, lam


def check_three_algorithms(model, rng, samples=3, inverse_tolerance=1e-13, inputs=None):
    """The composite-body mass matrix is the derivative of the Newton-Euler inverse
    dynamics in ``qdd``, symmetric positive definite; the articulated-body forward
    dynamics inverts the Newton-Euler pass and agrees with solving with ``D``."""
    inputs = random_inputs if inputs is None else inputs
    e = model.expressions
    f = _function(
        e,
        [e.q, e.qd, e.qdd, e.tau, e.lam],
        [e.mass_matrix, ca.jacobian(e.inverse_dynamics, e.qdd), e.inverse_dynamics],
    )
    forward = _function(e, [e.q, e.qd, e.tau, e.lam], [e.forward_dynamics])
    for _ in range(samples):
        q, qd, tau, lam = inputs(rng, model)
        qdd = np.array(forward(q, qd, tau, lam, model.parameters)).ravel()
        d, d_rnea, back = (np.array(v) for v in f(q, qd, qdd, tau, lam, model.parameters))
        assert_close(d, d_rnea, atol=1e-14 * np.abs(d).max(), what="D against d(tau)/d(qdd)")
        assert_close(d, d.T, atol=0, what="symmetry")
        assert np.linalg.eigvalsh(d).min() > 0
        bias = np.array(f(q, qd, np.zeros(model.n), tau, lam, model.parameters)[2]).ravel()
        scale = np.abs(bias).max() + np.abs(tau).max()  # of the terms that cancel
        assert_close(back.ravel(), tau, atol=inverse_tolerance * scale, what="inverse(forward)")
        # D's condition number reaches 1e10 (20 paper segments): the accelerations differ
        # by as much; in tau both are exact to round-off
        solved = np.linalg.solve(d, tau - bias)
        assert_close(d @ (solved - qdd), 0.0, atol=1e-12 * scale, what="ABA vs solve")


def test_the_three_algorithms_agree(rng, model):
    check_three_algorithms(model, rng)


def test_ddot_minus_2c_is_skew_and_c_is_christoffel(rng, model):
    e = model.expressions
    d = e.mass_matrix
    a = ca.jacobian(d @ e.qd, e.q)
    d_dot = ca.jtimes(d, e.q, e.qd)
    f = _function(e, [e.q, e.qd], [d_dot - 2 * e.coriolis_matrix, 0.5 * (d_dot + a - a.T)])
    for _ in range(3):
        q, qd = random_state(rng, model)
        n, christoffel = (np.array(v) for v in f(q, qd, model.parameters))
        assert_close(n + n.T, 0.0, atol=1e-12 * np.abs(n).max(), what="Ddot - 2C skew")
        c = model.coriolis_matrix(q, qd)
        assert_close(c, christoffel, atol=1e-12 * np.abs(c).max(), what="C Christoffel")


def check_power_balance(model, rng, samples=3, inputs=None):
    """Along the forward dynamics, ``d(T + V_g + V_e)/dt = qd . (tau + K^T lambda - R qd)``:
    the inertial terms neither create nor destroy energy, with ``dT/dt = qd . D qdd + qd .
    Ddot qd / 2``."""
    inputs = random_inputs if inputs is None else inputs
    e = model.expressions
    qdd = e.forward_dynamics
    kinetic_rate = ca.dot(e.qd, e.mass_matrix @ qdd) + 0.5 * ca.dot(
        e.qd, ca.jtimes(e.mass_matrix, e.q, e.qd) @ e.qd
    )
    potential_rate = ca.dot(e.gravity_force + e.elastic_force, e.qd)
    supplied = ca.dot(e.qd, e.tau + e.creep_force - e.damping_force)
    f = _function(e, [e.q, e.qd, e.tau, e.lam], [kinetic_rate + potential_rate, supplied])
    for _ in range(samples):
        q, qd, tau, lam = inputs(rng, model)
        balance, supplied_value = (float(v) for v in f(q, qd, tau, lam, model.parameters))
        scale = abs(float(np.dot(qd, model.mass_matrix(q) @ qd))) + abs(supplied_value)
        assert balance == pytest.approx(supplied_value, abs=1e-10 * scale)


def test_power_balance(rng, model):
    check_power_balance(model, rng)


def test_forces_are_gradients_of_the_energies(rng, model):
    e = model.expressions
    energy = ca.Function("V", [e.q, e.p], [e.gravity_energy, e.elastic_energy])
    newton_euler = ca.Function("tau", [e.q, e.qd, e.qdd, e.lam, e.p], [e.inverse_dynamics])
    h = 1e-6
    for _ in range(3):
        q, _ = random_state(rng, model)
        fd = np.zeros((2, model.n))
        scale = model.robot.coordinate_scale()
        for j in range(model.n):
            step = np.zeros(model.n)
            step[j] = h * scale[j]
            plus = np.array([float(v) for v in energy(q + step, model.parameters)])
            minus = np.array([float(v) for v in energy(q - step, model.parameters)])
            fd[:, j] = (plus - minus) / (2 * step[j])
        gravity, elastic = model.gravity_force(q), model.elastic_force(q)
        assert_close(gravity, fd[0], rtol=1e-6, scale=np.abs(gravity).max(), what="gravity")
        assert_close(elastic, fd[1], rtol=1e-6, scale=np.abs(elastic).max(), what="elastic")
        zero = np.zeros(model.n)
        at_rest = np.array(newton_euler(q, zero, zero, np.zeros(model.n_creep), model.parameters))
        g_scale = np.abs(gravity).max()
        assert_close(at_rest.ravel() - elastic, gravity, rtol=1e-11, scale=g_scale, what="G")


def _bodies(model):
    """Every mass of the robot as (element, local s or None, mass, inertia in its frame,
    centre in the element's base frame for a rigid body), independent of the model's
    Newton-Euler pass: slices on 40 Gauss nodes."""
    s, w = np.polynomial.legendre.leggauss(40)
    s, w = 0.5 * (s + 1), 0.5 * w
    for i, element in enumerate(model.robot.segments):
        if isinstance(element, sc.RigidBody):
            yield i, None, element.mass, element.inertia, element.centre_of_mass
            continue
        inertia = getattr(element, "slice_inertia", None)
        if inertia is None or isinstance(element, sc.Segment):
            inertia = element.radius**2 * np.array([0.25, 0.25, 0.5])
        for sk, wk in zip(s, w, strict=True):
            yield i, sk, wk * element.mass, np.diag(wk * element.mass * inertia), None


def kinetic_energy_from_pose(model, q, qd, h=1e-6):
    """Independent reference: each slice's (or body's) energy from finite-difference
    velocities of the model's poses."""
    n_elements = model.robot.n_segments
    energy = 0.0
    for i, sk, mass, inertia, centre in _bodies(model):
        point = (i + (sk if sk is not None else 0.0)) / n_elements
        poses = [model.pose(q + k * h * qd, point) for k in (1, -1, 0)]
        if centre is not None:  # the rigid body's base frame is the previous tip
            positions = [p.position + p.rotation @ centre for p in poses]
        else:
            positions = [p.position for p in poses]
        velocity = (positions[0] - positions[1]) / (2 * h)
        omega_hat = poses[2].rotation.T @ (poses[0].rotation - poses[1].rotation) / (2 * h)
        omega = np.array([omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]])
        energy += 0.5 * (mass * velocity @ velocity + omega @ inertia @ omega)
    return energy


def test_kinetic_energy_matches_pose_velocities(rng, model):
    for _ in range(3):
        q, qd = random_state(rng, model)
        reference = kinetic_energy_from_pose(model, q, qd)
        assert model.kinetic_energy(q, qd) == pytest.approx(reference, rel=1e-7)


@pytest.mark.parametrize("kind", KINDS)
def test_energy_is_conserved_without_dissipation(rng, kind):
    robot = robots(damping=False)[kind]
    if robot.n_creep:
        robot = robot.replace(
            segments=tuple(s.replace(creep=None) if s.n_creep else s for s in robot.segments)
        )
    model = sc.Model(robot, compile=False)
    q0, qd0 = random_state(rng, model)
    x0 = np.concatenate([q0, qd0])
    rhs = model.rhs()
    result = solve_ivp(rhs, (0.0, 0.05), x0, method="DOP853", rtol=1e-11, atol=1e-13,
                       t_eval=np.linspace(0, 0.05, 6))  # fmt: skip
    assert result.success
    n = model.n
    energies = [model.energy(x[:n], x[n:]) for x in result.y.T]
    drift = np.abs(np.array(energies) - energies[0]).max() / abs(energies[0])
    assert drift < 1e-8, f"relative energy drift {drift:.2e}"


def test_compiled_equals_virtual_machine(rng):
    robot = robots()["mixed"]
    compiled, vm = sc.Model(robot), sc.Model(robot, compile=False)
    for _ in range(2):
        q, qd = random_state(rng, vm)
        tau = rng.normal(size=vm.n) * 1e-3
        for name, args in [
            ("forward_dynamics", (q, qd, tau, np.zeros(vm.n_creep))),
            ("mass_matrix", (q,)),
            ("coriolis_matrix", (q, qd)),
            ("potential_energy", (q,)),
            ("jacobian", (q, 0.6)),
            ("tip_pose", (q,)),
        ]:
            a, b = getattr(compiled, name)(*args), getattr(vm, name)(*args)
            if isinstance(a, tuple) or hasattr(a, "rotation"):
                for x, y in zip(tuple(a), tuple(b), strict=True):
                    assert_close(x, y, rtol=1e-13, scale=np.abs(y).max(), what=name)
            else:
                assert_close(a, b, rtol=1e-13, scale=np.abs(b).max(), what=name)


def six_strain_gripper_robot():
    """A six-strain segment carrying a gripper: the robot the figures, scenario files,
    identification and C export are checked on."""
    return sc.Robot(segments=(six_strain_segment(), gripper()))


def twisted(robot, twist=10.0, bend=0.0):
    """The rest configuration of a robot whose first element is a six-strain segment,
    twisted by ``twist`` [1/m] (and bent by ``bend`` [1/m] about y)."""
    q = robot.rest_configuration()
    q[sc.STRAINS.index("twist")] = twist
    q[sc.STRAINS.index("bend_y")] = bend
    return q


def test_spans_place_each_element_in_the_material_coordinate(rng):
    """``Robot(spans=...)`` gives each element its share of ``s``: the same material point
    (element and local coordinate) has the same pose and Jacobian under any spans."""
    equal = robots()["mixed"]
    weights = np.array([3.0, 0.5, 2.0, 1.0])
    spanned = equal.replace(spans=weights)
    a, b = sc.Model(equal, compile=False), sc.Model(spanned, compile=False)
    bounds = np.concatenate([[0.0], np.cumsum(weights) / weights.sum()])
    assert_close(spanned.span_bounds, bounds, rtol=1e-15, what="bounds")
    q, _ = random_state(rng, a)
    for i in range(4):
        for local in (0.0, 0.3, 0.999):
            s_equal = (i + local) / 4
            s_spanned = bounds[i] + local * (bounds[i + 1] - bounds[i])
            pa, pb = a.pose(q, s_equal), b.pose(q, s_spanned)
            assert_close(pb.position, pa.position, atol=1e-15, what=f"position {i}, {local}")
            assert_close(pb.rotation, pa.rotation, atol=1e-14, what=f"rotation {i}, {local}")
            assert_close(b.jacobian(q, s_spanned), a.jacobian(q, s_equal), atol=1e-14)
    # the parameter vector carries them; equal spans stay the default
    assert spanned.with_parameter_vector(spanned.parameter_vector()).spans.tolist() == [
        3.0, 0.5, 2.0, 1.0
    ]  # fmt: skip
    assert equal.with_parameter_vector(equal.parameter_vector()).spans is None
    assert spanned.with_segments(6).spans.tolist() == [3.0, 0.5, 2.0, 1.0, 3.0, 0.5]


@pytest.mark.parametrize(
    ("spans", "message"),
    [([1.0, 2.0], r"spans must have shape \(4,\)"), ([1.0, 0.0, 1.0, 1.0], "spans must be > 0")],
)
def test_bad_spans_are_refused(spans, message):
    with pytest.raises(sc.ParameterError, match=message):
        robots()["mixed"].replace(spans=spans)
