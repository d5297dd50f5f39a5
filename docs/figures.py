"""The figures of the documentation's own pages, drawn with tumble's public API and matplotlib.

    python docs/figures.py             # every figure, written to docs/images/NAME.png
    python docs/figures.py NAME ...    # only these (the names of FIGURES)

Each figure function runs what its page runs, at the sizes given by its keyword arguments (the pages' sizes by
default; ``tests/test_doc_figures.py`` runs every one tiny), and returns a :class:`matplotlib.figure.Figure`. The
whole set takes a few seconds on 2 cores once numba's cache is warm (the first run compiles the heavy top's tangent
loops and the closed form, as the tutorials' examples do). The bundled studies' figures are not drawn here:
``tumble run NAME`` draws them, and ``studies/gallery/`` keeps one set for the gallery page.
"""

import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import tumble

IMAGES = Path(__file__).resolve().parent / "images"
DPI = 150
REGULAR, CHAOTIC = "C0", "C3"

# The tutorial "Regular or chaotic?" (docs/tutorials/regular-or-chaotic.md): an asymmetric heavy top, its centre of
# mass on no principal axis, and two releases of it, one regular and one chaotic (state w1 w2 w3 g1 g2 g3).
TOP = dict(moments=(1.0, 1.6, 2.2), mgl=1.0, centre=(0.6, 0.3, 1.0))
RELEASES = {"regular release": [0.5, 0.3, 2.0, 0.3, 0.1, 1.0],
            "chaotic release": [0.04071382, 0.0164995, -0.85749567, 0.35671917, -0.78540276, 0.5058596]}
EXAMPLES_HORIZON = 200.0  # s: the tutorial's examples run to here; the figures run further


def _top_and_releases():
    """The tutorial's heavy top and its two releases (the up vector normalised, as the page does), shape (2, 6)."""
    top = tumble.models.HeavyTop(TOP["moments"], TOP["mgl"], centre=TOP["centre"])
    # each up vector normalised on its own, as the page does: a chaotic orbit's exponent at 1000 s follows the
    # last bit of its start (its separation grows like exp(0.1 t))
    return top, np.array([[*state[:3], *(np.asarray(state[3:]) / np.linalg.norm(state[3:]))]
                          for state in RELEASES.values()])


def _figure(width=6.0, height=3.4):
    return Figure(figsize=(width, height), layout="constrained")


def _mark_examples_horizon(ax, horizon):
    if horizon > EXAMPLES_HORIZON:
        ax.axvline(EXAMPLES_HORIZON, color="0.6", lw=0.8, ls=":", label=f"T = {EXAMPLES_HORIZON:g} s, the examples'")


def megno_against_time(horizon=1000.0, dt=0.01, points=80):
    """MEGNO ⟨Y⟩ against the horizon for the tutorial's two releases: near 2 for the regular one, growing like
    λ1 t / 2 for the chaotic one (λ1 from :func:`tumble.lyapunov` over the same horizon). ``<Y>`` is the value at
    the end of a run, so each of the ``points`` horizons is one call of :func:`tumble.megno`."""
    top, states = _top_and_releases()
    times = np.linspace(horizon / points, horizon, points)
    megno = np.array([tumble.megno(top, states, t, dt)["megno"].values for t in times])
    lambda1 = tumble.lyapunov(top, states, horizon, dt, exponents=1)["exponent"].values[:, 0]
    fig = _figure()
    ax = fig.add_subplot()
    for k, (name, colour) in enumerate(zip(RELEASES, (REGULAR, CHAOTIC))):
        ax.plot(times, megno[:, k], color=colour, label=name)
    ax.plot(times, lambda1[1] * times / 2, color=CHAOTIC, lw=0.8, ls="--",
            label=f"λ1 t / 2, λ1 = {lambda1[1]:.3f} 1/s (tumble.lyapunov)")
    ax.axhline(2.0, color=REGULAR, lw=0.8, ls="--", label="2: a regular orbit's limit")
    _mark_examples_horizon(ax, horizon)
    ax.set(xlabel="horizon t (s)", ylabel="MEGNO ⟨Y⟩ at t", xlim=(0, horizon), ylim=(0, None))
    ax.legend(loc="upper left", fontsize="small", frameon=False)
    return fig


def lyapunov_against_time(horizon=1000.0, dt=0.01, save_every=100):
    """The finite-time largest Lyapunov exponent λ1(t) of the tutorial's two releases (Benettin's renormalisation
    every second) against ``ln t / t``, the decay of a regular orbit's."""
    top, states = _top_and_releases()
    ds = tumble.lyapunov(top, states, horizon, dt, exponents=1, save_every=save_every)
    t = ds["time"].values
    fig = _figure()
    ax = fig.add_subplot()
    for k, (name, colour) in enumerate(zip(RELEASES, (REGULAR, CHAOTIC))):
        ax.loglog(t, np.abs(ds["finite_time"].values[k, :, 0]), color=colour, label=name)
    reference = t > 1.0  # ln t / t is positive past 1 s
    ax.loglog(t[reference], np.log(t[reference]) / t[reference], color="k", lw=0.8, ls="--",
              label="ln t / t (a regular orbit)")
    _mark_examples_horizon(ax, horizon)
    ax.set(xlabel="time t (s)", ylabel="finite-time λ1 (1/s)")
    ax.legend(loc="lower left", fontsize="small", frameon=False)
    return fig


def gali_against_time(horizon=1000.0, dt=0.01, save_every=100):
    """GALI_2 of the tutorial's two releases: about constant on the regular one (its torus has two dimensions),
    falling like exp(-(λ1 - λ2) t) to round-off on the chaotic one."""
    top, states = _top_and_releases()
    ds = tumble.gali(top, states, horizon, dt, k=2, save_every=save_every)
    spectrum = tumble.lyapunov(top, states, horizon, dt, exponents=2)["exponent"].values[1]
    t = ds["time"].values
    fig = _figure()
    ax = fig.add_subplot()
    for k, (name, colour) in enumerate(zip(RELEASES, (REGULAR, CHAOTIC))):
        ax.semilogy(t, np.maximum(ds["gali"].values[k], 1e-17), color=colour, label=name)
    rate = spectrum[0] - spectrum[1]
    ax.semilogy(t, np.exp(-rate * t), color=CHAOTIC, lw=0.8, ls="--",
                label=f"exp(−(λ1 − λ2) t), λ1 − λ2 = {rate:.3f} 1/s")
    _mark_examples_horizon(ax, horizon)
    ax.set(xlabel="time t (s)", ylabel="GALI₂", xlim=(0, horizon), ylim=(1e-17, 2.0))
    ax.legend(loc="center right", fontsize="small", frameon=False)
    return fig


def integrator_error(t_end=20.0, dt=0.01, save_every=10):
    """The tutorial "Checking an integrator": the body (1, 2, 3) kg m² spun about its intermediate axis, tilted by
    1 mrad, through its flip; above its angular velocity (rk4), below each method's error against the closed form."""
    body = tumble.Body(1.0, 2.0, 3.0)
    w0 = np.array([[1e-3, 1.0, 0.0]])
    fig = _figure(6.0, 4.6)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(1, 1.3))
    for method, colour in (("rk4", "C0"), ("splitting4", "C2"), ("implicit_midpoint", "C1")):
        ds = tumble.integrate(body, w0, t_end, dt, method=method, save_every=save_every)
        t, omega = ds["time"].values, ds["omega"].values[0]
        error = np.abs(omega - tumble.exact.omega(body, w0, t)[0]).max(axis=-1)
        bottom.semilogy(t[1:], np.maximum(error[1:], 1e-17), color=colour, label=method)
        if method == "rk4":
            for axis in range(3):
                top.plot(t, omega[:, axis], label=f"ω{axis + 1}")
    top.set(ylabel="ω (rad/s), rk4")
    top.legend(loc="center left", fontsize="small", frameon=False)
    bottom.set(xlabel="time t (s)", ylabel="|ω − ω exact| (rad/s)", xlim=(0, t_end))
    bottom.legend(loc="lower right", fontsize="small", frameon=False, ncols=3)
    return fig


def gpu_ensemble(t_end=20.0, dt=0.01, save_every=5, samples=8):
    """The tutorial "The GPU": the ensemble of its examples (spins about the intermediate axis of the body (1, 2, 3),
    tilted by 1 mrad) through the 20 s of its flip example: ω2 of each spin (rk4, on the CPU) and the flip times of
    the closed form (dots), which the device reproduces to the bit."""
    body = tumble.Body(1.0, 2.0, 3.0)
    w0 = tumble.sampling.perturbed_spins(body, 2, spin=1.0, amplitude=1e-3, samples=samples, seed=0)
    ds = tumble.integrate(body, w0, t_end, dt, method="rk4", save_every=save_every)
    flips = tumble.run_ensemble(body, w0, t_end, dt, method="exact", axis=2, max_flips=2, progress=False).flips
    fig = _figure(6.0, 3.0)
    ax = fig.add_subplot()
    t = ds["time"].values
    for k in range(samples):
        ax.plot(t, ds["omega"].values[k, :, 1], color=f"C{k % 10}", lw=1.0)
        first = flips[k, 0]
        if np.isfinite(first):
            ax.plot(first, np.interp(first, t, ds["omega"].values[k, :, 1]), "o", color=f"C{k % 10}", ms=4)
    ax.set(xlabel="time t (s)", ylabel="ω2 (rad/s)", xlim=(0, t_end),
           title=f"{samples} spins, rk4 on the CPU; dots: the closed form's flip times", )
    ax.title.set_fontsize("medium")
    return fig


#: The figures, by name: docs/images/NAME.png.
FIGURES = {
    "megno_against_time": megno_against_time,
    "lyapunov_against_time": lyapunov_against_time,
    "gali_against_time": gali_against_time,
    "integrator_error": integrator_error,
    "gpu_ensemble": gpu_ensemble,
}


def main(names=()):
    unknown = sorted(set(names) - set(FIGURES))
    if unknown:
        raise SystemExit(f"no such figures: {', '.join(unknown)} (figures: {', '.join(FIGURES)})")
    IMAGES.mkdir(exist_ok=True)
    for name in names or FIGURES:
        path = IMAGES / f"{name}.png"
        FIGURES[name]().savefig(path.with_suffix(".part.png"), dpi=DPI)
        path.with_suffix(".part.png").replace(path)
        print(f"wrote {path.relative_to(IMAGES.parents[1])}")


if __name__ == "__main__":
    main(sys.argv[1:])
