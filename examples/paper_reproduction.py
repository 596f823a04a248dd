"""The numbers of docs/paper-reproduction.md, measured on the paper's case (section 4.2).

Run:  python examples/paper_reproduction.py [--figures DIR]

Simulates preset ifac2020 from q0 = (0.064, 25, 0), qd0 = (0, 0, 1500) and prints the
frequencies and decay rates of the elongation and bending oscillations (from the
trajectory, and from the linearization for comparison), the energy, the equilibrium
reached, the equilibrium with the authors' l0 = 0.064 m and rest bend of 0.01 rad, and
whether 1 ms output resolves the motion. With --figures, also writes a close-up of the
first second (the figures of the full 10 s come from ``softcurve simulate``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.signal import butter, find_peaks, sosfiltfilt

import softcurve as sc
from softcurve.figures import save_figure
from softcurve.simulation.solvers import linearization_rates

Q0, QD0 = [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]


def zero_crossings(y, t):
    i = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
    return t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])


def modes(model, x):
    q, qd, lam = model.split_state(x)
    eigenvalues = np.linalg.eigvals(sc.linearize(model, q, qd, lam).A)
    oscillating = sorted(
        {
            (round(float(-e.real), 2), round(float(abs(e.imag)) / (2 * np.pi), 2))
            for e in eigenvalues
            if abs(e.imag) > 1e-6
        }
    )
    return oscillating, sorted(float(-e.real) for e in eigenvalues if abs(e.imag) <= 1e-6)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, help="folder for the close-up figure")
    args = parser.parse_args()
    model = sc.Model(sc.presets.ifac2020())
    run = sc.simulate(model, Q0, QD0, t_final=10.0)
    fine = sc.simulate(model, Q0, QD0, t_final=1.0, dt=1e-4)
    t, q = fine.t, fine.q
    print(f"run: {run.message}; {1e3 * run.stats['wall_time']:.1f} ms integrating")
    ratio = linearization_rates(model, run.x[0])[0]
    print(f"stiffness ratio at x0: {ratio:.2f} -> {run.stats['method']}")

    print("\nbending (kx, ky): frequency from successive zero crossings [Hz]")
    for name, y in (("kx", q[:, 1]), ("ky", q[:, 2])):
        crossings = zero_crossings(y, t)
        print(f"  {name}: " + " ".join(f"{f:.2f}" for f in 0.5 / np.diff(crossings)[:12]))
    kappa = np.hypot(q[:, 1], q[:, 2])
    peaks, _ = find_peaks(kappa)
    late = peaks[t[peaks] > 0.1]
    rate = -np.polyfit(t[late], np.log(kappa[late]), 1)[0]
    print(f"  |kappa| peaks decay as exp(-{rate:.2f} t) for t > 0.1 s")

    high = sosfiltfilt(butter(4, 25.0, "highpass", fs=1e4, output="sos"), q[:, 0])
    peaks, _ = find_peaks(high[: int(0.3 / 1e-4)])
    print("\nlength l, fast part (high-pass 25 Hz): frequency from successive peaks [Hz]")
    print("  " + " ".join(f"{f:.1f}" for f in 1 / np.diff(t[peaks])))
    print("  amplitude [mm]: " + " ".join(f"{1e3 * a:.3f}" for a in high[peaks]))
    slow = q[:, 0] - high
    peaks, _ = find_peaks(slow)
    print("length l, slow part: frequency from successive peaks [Hz]")
    print("  " + " ".join(f"{f:.2f}" for f in 1 / np.diff(t[peaks])[:10]))

    for label, x in (("initial state", run.x[0]), ("final state", run.x[-1])):
        oscillating, real = modes(model, x)
        print(
            f"\nlinearization at the {label}: (decay rate [1/s], frequency [Hz]) "
            f"{oscillating}; real modes [1/s] {[round(r, 1) for r in real]}"
        )

    energy = run.energy()
    print(
        f"\nenergy T + V: {energy[0]:.6f} J at t = 0, "
        + ", ".join(f"{energy[round(s / 1e-3)]:.6f} J at {s:g} s" for s in (0.1, 0.5, 1, 10))
    )
    print(f"final state q = {run.q[-1].tolist()}, |qd| = {np.abs(run.qd[-1]).max():.2e}")
    print(f"compression by gravity l0 - l = {1e3 * (0.0644 - run.q[-1, 0]):.4f} mm")

    coarse = sc.simulate(model, Q0, QD0, t_final=1.0)
    difference = np.abs(fine.x[::10] - coarse.x).max(axis=0)
    print(
        "\n1 ms against 0.1 ms output, same times: max |difference| in "
        f"l {difference[0]:.1e} m, kx {difference[1]:.1e} 1/m, ky {difference[2]:.1e} 1/m"
    )
    print(f"  max l on the 1 ms grid {coarse.q[:, 0].max():.6f} m, on 0.1 ms {q[:, 0].max():.6f} m")

    segment = model.robot.segments[0].replace(rest_length=0.064)
    authors = sc.Model(model.robot.replace(segments=(segment,)))
    straight = sc.simulate(authors, Q0, QD0, t_final=10.0).q[-1]
    bending = segment.bending_stiffness
    k_b0 = bending.a1 - bending.a2
    offset = np.array([0.0, k_b0 * 0.01 * 0.064, 0.0])  # rest bend 0.01 rad, linearized
    bent = sc.simulate(authors, Q0, QD0, tau=offset, t_final=10.0).q[-1]
    print(
        "\nwith the authors' l0 = 0.064 m: equilibrium "
        f"l = {straight[0]:.5f} m, kappa = {np.hypot(*straight[1:]):.2e} 1/m"
    )
    print(
        "  and their rest bend 0.01 rad (as the constant force k_b(0) beta0 l): "
        f"l = {bent[0]:.5f} m, kappa = {np.hypot(*bent[1:]):.4f} 1/m"
    )

    if args.figures:
        import matplotlib.pyplot as plt

        figure = fine.plot()
        for ax in figure.axes:
            ax.set_xlim(0.0, 1.0)
        figure.axes[0].set_title("State trajectories, first second (output every 0.1 ms)")
        path = args.figures / "paper-states-first-second.png"
        args.figures.mkdir(parents=True, exist_ok=True)
        save_figure(figure, path)
        plt.close(figure)
        print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
